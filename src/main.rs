//! `stereo-depth`: metric depth from a rectified stereo pair.
//!
//! `main` only maps the outcome of [`run`] to an exit status: 0 success, 1 runtime errors (files
//! missing, unreadable, mismatched, unwritable), 2 usage errors (clap's and our own argument
//! checks). A closed stdout (`stereo-depth ... | head`) ends the program normally.

#[macro_use]
mod error;
mod allocator;
mod args;
mod batch;
mod calc;
mod checks;
mod config;
mod degrade_cmd;
mod discover;
mod eval_cmd;
mod eval_folder;
mod info;
mod limits;
mod pair;
mod rectify_cmd;
mod report;
mod writers;

use std::io::{self, Write};
use std::process::ExitCode;

use anyhow::Context;
use clap::error::{ContextKind, ContextValue, ErrorKind};

use crate::args::{Cli, Command};
use crate::config::{
    BatchConfig, BatchMergeConfig, CalcConfig, DegradeConfig, EvalConfig, EvalFolderConfig, PairConfig,
};
use crate::error::{one_line, UsageError};

fn main() -> ExitCode {
    allocator::reuse_freed_memory();
    match run() {
        Ok(code) => code,
        Err(err) if is_broken_pipe(&err) => ExitCode::SUCCESS,
        Err(err) => {
            let message = one_line(&err);
            let _ = writeln!(io::stderr().lock(), "stereo-depth: error: {message}");
            let usage = err.chain().any(|cause| cause.is::<UsageError>());
            ExitCode::from(if usage { 2 } else { 1 })
        }
    }
}

fn run() -> anyhow::Result<ExitCode> {
    let cli = match Cli::try_parse_with_defaults() {
        Ok(cli) => cli,
        Err(err) => {
            let code = ExitCode::from(err.exit_code().clamp(0, 255) as u8);
            // --help and --version end up here too, with exit status 0, and so does the help
            // shown when no argument is given: printed whole.
            if !err.use_stderr() || err.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand {
                err.print().context("cannot print the usage message")?;
                return Ok(code);
            }
            let _ = writeln!(io::stderr().lock(), "stereo-depth: error: {}", clap_one_line(&err));
            return Ok(code);
        }
    };
    let mut stdout = io::stdout().lock();
    match cli.command {
        Some(Command::Batch(args)) => {
            let config = BatchConfig::from_args(*args)?;
            return batch::run(&config, &mut stdout);
        }
        Some(Command::BatchMerge(args)) => {
            let config = BatchMergeConfig::from_args(args)?;
            return batch::merge(&config, &mut stdout);
        }
        Some(Command::Calc(args)) => {
            let config = CalcConfig::from_args(args)?;
            calc::run(&config, &mut stdout)?;
        }
        Some(Command::Info(args)) => info::run(&args.file, &mut stdout)?,
        Some(Command::Degrade(args)) => {
            let config = DegradeConfig::from_args(args)?;
            degrade_cmd::run(&config, &mut stdout)?;
        }
        Some(Command::Rectify(args)) => rectify_cmd::run(&args, &mut stdout)?,
        Some(Command::EvalFolder(args)) => {
            let config = EvalFolderConfig::from_args(*args)?;
            eval_folder::run(&config, &mut stdout)?;
        }
        Some(Command::Eval(args)) => {
            let config = EvalConfig::from_args(args)?;
            eval_cmd::run(&config, &mut stdout)?;
        }
        None => {
            let threads = cli.pair.threads;
            let config = PairConfig::from_args(cli.pair)?;
            if let Some(threads) = threads {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(threads.into())
                    .build_global()
                    .context("cannot start the worker threads")?;
            }
            pair::run(&config, &mut stdout)?;
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// clap's error as one line: its message, and its tip when it has one (the usage lines and the
/// pointer to --help are left out); missing arguments are named, see [`missing_arguments`].
fn clap_one_line(err: &clap::Error) -> String {
    if let Some(line) = missing_arguments(err) {
        return line;
    }
    let text = err.render().to_string();
    let mut lines = text.lines().map(str::trim).filter(|l| !l.is_empty());
    let first = lines.next().unwrap_or("invalid arguments");
    let mut message = first.strip_prefix("error: ").unwrap_or(first).to_string();
    for line in lines {
        if let Some(tip) = line.strip_prefix("tip: ") {
            message.push_str("; ");
            message.push_str(tip);
        }
    }
    message
}

/// A missing required argument: clap lists them one per line below its message, which alone
/// names nothing, so they are named here from the error's context, with the usage of the
/// (sub)command (one line when clap gives several).
fn missing_arguments(err: &clap::Error) -> Option<String> {
    if err.kind() != ErrorKind::MissingRequiredArgument {
        return None;
    }
    let Some(ContextValue::Strings(missing)) = err.get(ContextKind::InvalidArg) else {
        return None;
    };
    let mut line = format!("missing {}", missing.join(", "));
    if let Some(ContextValue::StyledStr(usage)) = err.get(ContextKind::Usage) {
        let usage = usage.to_string();
        let usage = usage.trim_start().strip_prefix("Usage:").unwrap_or(&usage);
        let forms: Vec<&str> = usage.lines().map(str::trim).filter(|l| !l.is_empty()).collect();
        line.push_str(&format!("; usage: {} (see --help)", forms.join(" | ")));
    }
    Some(line)
}

fn is_broken_pipe(err: &anyhow::Error) -> bool {
    err.chain()
        .any(|cause| cause.downcast_ref::<io::Error>().is_some_and(|e| e.kind() == io::ErrorKind::BrokenPipe))
}
