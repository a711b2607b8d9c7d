//! `jello`: run, create and inspect jello worlds from the terminal, and view them in a browser.

mod commands;
mod error;
mod export;
mod frames;
mod fsio;
mod progress;

use clap::{Parser, Subcommand};

/// Jello: a mass-spring soft-body simulator of the classic jello cube.
#[derive(Parser, Debug)]
#[command(name = "jello", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Run a world headless and print a summary; optionally save frames and the final state.
    Run(commands::run::RunArgs),
    /// Write a new world file.
    Create(commands::create::CreateArgs),
    /// Describe a world file: header, counts, energies, stable time steps.
    Info(commands::info::InfoArgs),
    /// Measure steps/s and spring evaluations/s on the benchmark scene.
    Bench(commands::bench::BenchArgs),
    /// Serve the browser viewer on 127.0.0.1 and print its URL.
    View(commands::view::ViewArgs),
}

fn main() {
    let cli = Cli::parse();
    // A JELLO_SIMD the core cannot honour is reported before anything runs.
    if let Err(e) = jello_core::simd::tier_from_env() {
        eprintln!("jello: error: {e}");
        std::process::exit(error::EXIT_USAGE);
    }
    let result = match cli.command {
        Command::Run(args) => commands::run::run(args),
        Command::Create(args) => commands::create::create(args),
        Command::Info(args) => commands::info::info(args),
        Command::Bench(args) => commands::bench::bench(args),
        Command::View(args) => commands::view::view(args),
    };
    if let Err(e) = result {
        eprintln!("jello: error: {e}");
        std::process::exit(e.code);
    }
}
