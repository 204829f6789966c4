//! The `gharial` command-line tool.

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "gharial", version, about = "Constrained trajectory optimization for robots")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// List the built-in problems and solvers.
    List,
}

fn main() {
    let cli = Cli::parse();
    match cli.command {
        Command::List => {
            println!("solvers: (none yet)");
            println!("problems: (none yet)");
        }
    }
}
