//! Arguments to typed, validated options: times, time grids, counts, seeds,
//! levels, the method and the Monte Carlo and `--ci` settings.

use btrel::compile::Method;

use super::args::{CiArgs, CurveArgs, MethodArg, SimArgs, TimeArgs};
use super::Failure;

/// Most time points one request may ask for.
pub(super) const MAX_POINTS: usize = 10_000_000;

/// `--ci` parsed: level, draws, seed.
pub(super) struct CiSettings {
    pub(super) level: f64,
    pub(super) draws: usize,
    pub(super) seed: u64,
}

/// The settings of `--ci`, `None` without it.
pub(super) fn ci_settings(args: &CiArgs) -> Result<Option<CiSettings>, Failure> {
    let Some(level) = args.ci.as_deref() else {
        return Ok(None);
    };
    let bad = || {
        Failure::input(format!(
            "--ci: '{level}' is not a confidence level (a number in (0, 1) such as 0.95, or a \
             percentage from 50 to 99.9 such as 90; the tree comes before --ci)"
        ))
    };
    let mut x: f64 = level
        .trim()
        .trim_end_matches('%')
        .parse()
        .map_err(|_| bad())?;
    if (50.0..100.0).contains(&x) {
        x /= 100.0;
    }
    if !(x > 0.0 && x < 1.0) {
        return Err(bad());
    }
    let draws = match args.ci_draws.as_deref() {
        None => btrel::uncertainty::DEFAULT_DRAWS as u64,
        Some(n) => parse_count("--ci-draws", n)?,
    };
    if !(2..=1_000_000).contains(&draws) {
        return Err(Failure::input("--ci-draws must be between 2 and 1000000"));
    }
    let seed = match args.ci_seed.as_deref() {
        None => btrel::uncertainty::DEFAULT_SEED,
        Some(s) => parse_seed("--ci-seed", s)?,
    };
    Ok(Some(CiSettings {
        level: x,
        draws: draws as usize,
        seed,
    }))
}

pub(super) fn method(m: MethodArg) -> Method {
    match m {
        MethodArg::Exact => Method::Exact,
        MethodArg::Book => Method::Book,
    }
}

/// A time given on the command line: finite and ≥ 0.
pub(super) fn parse_time(what: &str, s: &str) -> Result<f64, Failure> {
    let t: f64 = s
        .trim()
        .parse()
        .map_err(|_| Failure::input(format!("{what}: '{s}' is not a number")))?;
    if !t.is_finite() || t < 0.0 {
        return Err(Failure::input(format!(
            "{what}: {s} is not a valid time (times must be finite and >= 0)"
        )));
    }
    Ok(t)
}

pub(super) fn requested_times(args: &CurveArgs) -> Result<Vec<f64>, Failure> {
    grid_times(&args.grid)?.ok_or_else(|| {
        Failure::input("which times? give --times T1,T2,... or --t-end T [--points K | --dt D]")
    })
}

/// Times from `--times`, or from `--t-end` with `--points`/`--dt`; `None`
/// when neither is given.
pub(super) fn grid_times(grid: &TimeArgs) -> Result<Option<Vec<f64>>, Failure> {
    let (list, t_end, points, dt) = (
        &grid.times,
        grid.t_end.as_deref(),
        grid.points,
        grid.dt.as_deref(),
    );
    if !list.is_empty() {
        let times = list
            .iter()
            .map(|s| parse_time("--times", s))
            .collect::<Result<Vec<_>, _>>()?;
        if times.len() > MAX_POINTS {
            return Err(Failure::input(format!(
                "--times: at most {MAX_POINTS} times"
            )));
        }
        return Ok(Some(times));
    }
    let Some(end) = t_end else {
        return Ok(None);
    };
    let end = parse_time("--t-end", end)?;
    if end <= 0.0 {
        return Err(Failure::input(
            "--t-end must be > 0 (for the time 0 alone use --times 0)",
        ));
    }
    if let Some(dt) = dt {
        let dt = parse_time("--dt", dt)?;
        if dt <= 0.0 {
            return Err(Failure::input("--dt must be > 0"));
        }
        let count = (end / dt * (1.0 + 1e-12)).floor() + 1.0;
        if count > MAX_POINTS as f64 {
            return Err(Failure::input(format!(
                "--t-end / --dt gives {count:.0} points, more than the limit of {MAX_POINTS}"
            )));
        }
        // 0, D, 2D, ... up to T, and T itself when it is not on the grid
        let mut times: Vec<f64> = (0..count as usize)
            .map(|k| (k as f64 * dt).min(end))
            .collect();
        if times.last().is_some_and(|&last| last < end * (1.0 - 1e-12)) {
            times.push(end);
        }
        return Ok(Some(times));
    }
    let points = points.unwrap_or(101);
    if points == 0 || points > MAX_POINTS {
        return Err(Failure::input(format!(
            "--points must be between 1 and {MAX_POINTS}"
        )));
    }
    if points == 1 {
        return Ok(Some(vec![end]));
    }
    Ok(Some(
        (0..points)
            .map(|k| end * k as f64 / (points - 1) as f64)
            .collect(),
    ))
}

/// An optional time option (finite, ≥ 0).
pub(super) fn optional_time(what: &str, value: &Option<String>) -> Result<Option<f64>, Failure> {
    value.as_deref().map(|t| parse_time(what, t)).transpose()
}

/// An optional count option (see [`parse_count`]).
pub(super) fn optional_count(what: &str, value: &Option<String>) -> Result<Option<u64>, Failure> {
    value.as_deref().map(|n| parse_count(what, n)).transpose()
}

/// A count such as `1000000`, `1_000_000` or `1e6`.
pub(super) fn parse_count(what: &str, s: &str) -> Result<u64, Failure> {
    let clean = s.trim().replace('_', "");
    if let Ok(n) = clean.parse::<u64>() {
        return Ok(n);
    }
    match clean.parse::<f64>() {
        Ok(x) if x.is_finite() && x >= 0.0 && x.fract() == 0.0 && x < 1.8e19 => Ok(x as u64),
        _ => Err(Failure::input(format!(
            "{what}: '{s}' is not a whole number of runs (e.g. 100000 or 1e5)"
        ))),
    }
}

/// A seed: decimal or 0x hex, `_` allowed.
pub(super) fn parse_seed(what: &str, s: &str) -> Result<u64, Failure> {
    let t = s.trim();
    let parsed = match t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
        Some(hex) => u64::from_str_radix(&hex.replace('_', ""), 16),
        None => t.replace('_', "").parse::<u64>(),
    };
    parsed.map_err(|_| {
        Failure::input(format!(
            "{what}: '{s}' is not a seed (a whole number from 0 to 2^64-1, decimal or 0x hex)"
        ))
    })
}

pub(super) fn sim_options(
    args: &SimArgs,
    runs: u64,
    times: Vec<f64>,
    per_node: bool,
) -> Result<btrel::sim::SimOptions, Failure> {
    let seed = match args.seed.as_deref() {
        None => btrel::sim::DEFAULT_SEED,
        Some(s) => parse_seed("--seed", s)?,
    };
    Ok(btrel::sim::SimOptions {
        runs,
        seed,
        threads: args.threads.unwrap_or(0),
        times,
        per_node,
    })
}

/// A probability-like option in (0, 1): `0.95`, or a percentage `95`.
pub(super) fn parse_level(what: &str, s: &str) -> Result<f64, Failure> {
    let bad = || {
        Failure::input(format!(
            "{what}: '{s}' is not a level (a number in (0, 1) such as 0.95, or a percentage from \
             50 to 99.99 such as 95)"
        ))
    };
    let mut x: f64 = s.trim().trim_end_matches('%').parse().map_err(|_| bad())?;
    if (50.0..100.0).contains(&x) {
        x /= 100.0;
    }
    if !(x > 0.0 && x < 1.0) {
        return Err(bad());
    }
    Ok(x)
}

/// A positive finite number option.
pub(super) fn parse_positive(what: &str, s: &str) -> Result<f64, Failure> {
    match s.trim().parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 => Ok(x),
        _ => Err(Failure::input(format!("{what}: '{s}' is not a number > 0"))),
    }
}
