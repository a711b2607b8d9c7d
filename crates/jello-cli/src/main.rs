//! `jello`: run, create and inspect jello worlds from the terminal, and view them in a browser.

mod commands;
mod error;
mod export;
mod frames;
mod gpu;
mod progress;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};

/// Jello: a mass-spring soft-body simulator of the classic jello cube.
#[derive(Parser, Debug)]
#[command(name = "jello", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Run a world or scene headless and print a summary; optionally save frames, an animated
    /// glTF and the final state.
    Run(commands::run::RunArgs),
    /// Write a new world file, or a scene of bodies (.toml).
    Create(Box<commands::create::CreateArgs>),
    /// Write a closed mesh the project makes (torus, blob, mould) as OBJ, for `create --mesh`.
    Shape(commands::shape::ShapeArgs),
    /// Describe a world or scene file: header, bodies, energies, stable time steps.
    Info(commands::info::InfoArgs),
    /// Measure steps/s and spring evaluations/s on the benchmark scene.
    Bench(commands::bench::BenchArgs),
    /// Serve the browser viewer on 127.0.0.1 and print its URL.
    View(commands::view::ViewArgs),
}

/// When the reader of our output goes away (`jello info … | head`), `println!` panics on the
/// broken pipe, since Rust ignores SIGPIPE. Stop quietly instead, as a Unix tool killed by the
/// signal would (exit status 141 = 128 + SIGPIPE); every other panic is reported as usual.
fn quiet_on_broken_pipe() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let message = info
            .payload()
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| info.payload().downcast_ref::<&str>().copied())
            .unwrap_or("");
        if message.starts_with("failed printing to std") && message.contains("Broken pipe") {
            std::process::exit(141);
        }
        default(info);
    }));
}

fn main() {
    quiet_on_broken_pipe();
    let matches = Cli::command().get_matches();
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    // A JELLO_SIMD the core cannot honour is reported before anything runs.
    if let Err(e) = jello_core::compute::simd::tier_from_env() {
        eprintln!("jello: error: {e}");
        std::process::exit(error::EXIT_USAGE);
    }
    let result = match cli.command {
        Command::Run(args) => commands::run::run(args),
        Command::Create(args) => {
            let sub = matches
                .subcommand_matches("create")
                .expect("the create subcommand has its matches");
            commands::create::create(*args, sub)
        }
        Command::Shape(args) => commands::shape::shape(args),
        Command::Info(args) => commands::info::info(args),
        Command::Bench(args) => commands::bench::bench(args),
        Command::View(args) => commands::view::view(args),
    };
    if let Err(e) = result {
        eprintln!("jello: error: {e}");
        std::process::exit(e.code);
    }
}
