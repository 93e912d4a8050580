//! `--ci`: intervals from the fitted parameters' sampling uncertainty,
//! shared by `report`, `curve` and `check`.

use btrel::tree::Tree;

use super::input::ParamsSource;
use super::options::CiSettings;
use super::Failure;

/// The sampler of `--ci`: the params file's `fit:` statistics by node.
/// Refuses a tree in which nothing would vary.
pub(super) fn ci_sampler(
    tree: &Tree,
    source: Option<&ParamsSource>,
    ci: &CiSettings,
    values_per_draw: usize,
) -> Result<btrel::uncertainty::Sampler, Failure> {
    let Some(src) = source else {
        return Err(Failure::input(
            "--ci needs fitted parameters: an XML tree with a params file written by `btrel fit` \
             (its `fit:` statistics give the parameters' uncertainty); a YAML tree has none",
        ));
    };
    let stats = btrel::uncertainty::read_fit_stats(&src.text, &src.name).map_err(Failure::input)?;
    let sampler = btrel::uncertainty::Sampler::new(tree, &src.keys, &stats);
    if sampler.varied() == 0 {
        return Err(Failure::input(format!(
            "--ci: no parameter of this tree has `fit:` statistics in {} (write the file with \
             `btrel fit LOG... -o {}`), so there is no uncertainty to propagate",
            src.name, src.name
        )));
    }
    let values_per_draw = values_per_draw + sampler.kept_per_draw();
    if ci.draws.saturating_mul(values_per_draw) > btrel::uncertainty::MAX_VALUES {
        return Err(Failure::analysis(format!(
            "--ci: {} draws of {values_per_draw} figures exceed the limit of {} values; lower \
             --ci-draws",
            ci.draws,
            btrel::uncertainty::MAX_VALUES
        )));
    }
    Ok(sampler)
}

/// The notes of `--ci` on standard error: the intervals' level, draws, seed
/// and method, then the parameters held fixed and how the sampler drew the
/// others.
pub(super) fn ci_notes(ci: &CiSettings, sampler: &btrel::uncertainty::Sampler) {
    eprintln!(
        "note: {} intervals from {} draws (seed {}): {}",
        btrel::report::intervals::percent(ci.level),
        ci.draws,
        ci.seed,
        btrel::uncertainty::METHOD
    );
    if !sampler.fixed.is_empty() {
        eprintln!(
            "note: fixed (no `fit:` statistics in the params file): {}",
            sampler.fixed.join(", ")
        );
    }
    for h in sampler.held.iter().chain(&sampler.independent) {
        eprintln!("note: {h}");
    }
}
