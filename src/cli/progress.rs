//! Progress on standard error: the simulation's bar and the spinner of a
//! long exact computation (a terminal only).

use std::io;

use btrel::tree::Tree;

use super::Failure;

/// Runs a simulation with a progress bar on a terminal.
pub(super) fn run_simulation(
    tree: &Tree,
    node: usize,
    options: &btrel::sim::SimOptions,
) -> Result<btrel::sim::SimResult, Failure> {
    use std::io::IsTerminal;
    let nodes = if options.per_node {
        tree.subtree(node).len() as u64
    } else {
        1
    };
    let show = io::stderr().is_terminal() && options.runs.saturating_mul(nodes) >= 20_000_000;
    let bar = show.then(|| {
        let b = indicatif::ProgressBar::new(options.runs);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "simulating {bar:40} {pos}/{len} runs ({eta} left)",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b
    });
    let callback = |done: u64| {
        if let Some(b) = &bar {
            b.set_position(done);
        }
    };
    let result = btrel::sim::simulate_node(
        tree,
        node,
        options,
        bar.as_ref().map(|_| &callback as &(dyn Fn(u64) + Sync)),
    )
    .map_err(Failure::input);
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    result
}

/// A spinner with the elapsed time on standard error (a terminal only),
/// shown once the work it watches has taken more than a second: a curve of
/// a large mixed-timing tree can take minutes, with nothing else to show.
pub(super) struct Spinner(Option<indicatif::ProgressBar>);

impl Spinner {
    pub(super) fn start(message: String) -> Spinner {
        use std::io::IsTerminal;
        if !io::stderr().is_terminal() {
            return Spinner(None);
        }
        let bar = indicatif::ProgressBar::hidden();
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} {msg} ({elapsed}; `btrel simulate` estimates it in seconds)",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
        );
        bar.set_message(message);
        let watch = bar.clone();
        std::thread::spawn(move || {
            std::thread::sleep(std::time::Duration::from_secs(1));
            if !watch.is_finished() {
                watch.set_draw_target(indicatif::ProgressDrawTarget::stderr());
                watch.enable_steady_tick(std::time::Duration::from_millis(200));
            }
        });
        Spinner(Some(bar))
    }
}

impl Drop for Spinner {
    fn drop(&mut self) {
        if let Some(bar) = &self.0 {
            bar.finish_and_clear();
        }
    }
}
