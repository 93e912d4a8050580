//! Command-line interface: argument parsing and dispatch to the library.
//!
//! Exit codes: 0 success; 2 invalid input or usage (bad tree file, bad
//! option); 1 the analysis could not be completed (a budget exceeded, an
//! unsupported combination) or an internal error.
//!
//! Layout: [`args`] holds the clap definitions, [`options`] turns arguments
//! into typed, validated values, [`input`] reads trees, [`advice`] holds the
//! hints that name command-line flags, [`output`] writes the results; one
//! module per command.

use std::process::ExitCode;

use clap::Parser;

mod advice;
mod args;
mod check;
mod ci;
mod compare;
mod curve;
mod docs;
mod export;
mod fit;
mod input;
mod options;
mod output;
mod plot;
mod progress;
mod report;
mod sensitivity;
mod simulate;

use args::{Cli, Command};
use input::InputOptions;

/// An error with its exit code.
struct Failure {
    code: u8,
    message: String,
}

impl Failure {
    fn input(message: impl ToString) -> Failure {
        Failure {
            code: 2,
            message: message.to_string(),
        }
    }
    fn analysis(message: impl ToString) -> Failure {
        Failure {
            code: 1,
            message: message.to_string(),
        }
    }
}

pub fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            return ExitCode::from(if e.use_stderr() { 2 } else { 0 });
        }
    };
    let input = InputOptions {
        format: cli.input_format,
        params: cli.params,
        include: cli.include,
    };
    let result = match cli.command {
        Command::Report(args) => report::run(args, &input),
        Command::Check(args) => check::run(args, &input),
        Command::Fit(args) => fit::run(args, &input),
        Command::Sensitivity(args) => sensitivity::run(args, &input),
        Command::Curve(args) => curve::run(args, &input),
        Command::Compare(args) => compare::run(args, &input),
        Command::Simulate(args) => simulate::run(args, &input),
        Command::Export(args) => export::run(args, &input),
        Command::Plot(args) => plot::run(args, &input),
        Command::Completions { .. } | Command::Man { .. } if input.given() => {
            Err(Failure::input(advice::TREE_OPTIONS_WITHOUT_TREE))
        }
        Command::Completions { shell } => docs::completions(shell),
        Command::Man { command, output } => docs::man(command.as_deref(), output.as_deref()),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) => {
            eprintln!("error: {}", f.message);
            ExitCode::from(f.code)
        }
    }
}
