//! `completions` and `man`: the command line's own documentation.

use std::path::Path;

use super::args::Cli;
use super::output::emit;
use super::Failure;

pub(super) fn completions(shell: clap_complete::Shell) -> Result<(), Failure> {
    use clap::CommandFactory;
    let mut cmd = Cli::command();
    emit(None, |out| {
        clap_complete::generate(shell, &mut cmd, "btrel", out);
        Ok(())
    })
}

pub(super) fn man(command: Option<&str>, output: Option<&Path>) -> Result<(), Failure> {
    use clap::CommandFactory;
    let mut root = Cli::command();
    root.build();
    let page = match command {
        None => root,
        Some(name) => {
            let names: Vec<String> = root
                .get_subcommands()
                .map(|c| c.get_name().to_string())
                .collect();
            let sub = root.find_subcommand(name).cloned().ok_or_else(|| {
                Failure::input(format!(
                    "no command '{name}'; the commands are: {}",
                    names.join(", ")
                ))
            })?;
            sub.name(format!("btrel-{name}"))
        }
    };
    let mut text = Vec::new();
    clap_mangen::Man::new(page)
        .render(&mut text)
        .map_err(|e| Failure::analysis(format!("cannot render the manual page: {e}")))?;
    emit(output, |out| out.write_all(&text))
}
