//! The `gharial` command-line tool.

mod bench;

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
    /// Benchmarks.
    Bench {
        #[command(subcommand)]
        which: BenchCommand,
    },
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Proximal Riccati solver (serial and parallel) on the peers' random LQ problems.
    Riccati {
        /// Thread counts to time (1 = the serial solver), comma separated.
        #[arg(long, value_delimiter = ',', default_values_t = vec![1, 2])]
        threads: Vec<usize>,
        /// Horizons of the main series, comma separated.
        #[arg(long, value_delimiter = ',', default_values_t = vec![16, 32, 64, 128, 256, 512, 1024])]
        horizons: Vec<usize>,
        /// Dimensions `nx:nu:nc` of the main series.
        #[arg(long, default_value = "36:12:32")]
        dims: String,
        /// Extra cases `nx:nu:nc:N`, comma separated.
        #[arg(long, value_delimiter = ',', default_values_t = vec!["12:6:0:100".to_string(), "4:2:2:100".to_string()])]
        extra: Vec<String>,
        /// Constraint regularisation mu.
        #[arg(long, default_value_t = 1e-8)]
        mu: f64,
        /// Seed of the problem generator.
        #[arg(long, default_value_t = 42)]
        seed: u64,
        /// Time budget per case and solver, in seconds.
        #[arg(long, default_value_t = 1.0)]
        budget: f64,
        /// Passes over the case list (the budget is split between them).
        #[arg(long, default_value_t = 4)]
        rounds: usize,
        /// Iterative refinement steps.
        #[arg(long, default_value_t = 0)]
        refine: usize,
    },
}

fn parse_dims(s: &str, n: usize) -> Result<Vec<usize>, String> {
    let v: Result<Vec<usize>, _> = s.split(':').map(str::parse).collect();
    match v {
        Ok(v) if v.len() == n => Ok(v),
        _ => Err(format!("expected {n} integers separated by ':', got `{s}`")),
    }
}

fn main() {
    let cli = Cli::parse();
    match cli.command {
        Command::List => {
            println!("solvers: (none yet)");
            println!("problems: (none yet)");
        }
        Command::Bench {
            which:
                BenchCommand::Riccati {
                    threads,
                    horizons,
                    dims,
                    extra,
                    mu,
                    seed,
                    budget,
                    rounds,
                    refine,
                },
        } => {
            let parsed = parse_dims(&dims, 3).and_then(|d| {
                let extra = extra
                    .iter()
                    .filter(|e| !e.is_empty())
                    .map(|e| parse_dims(e, 4).map(|v| (v[0], v[1], v[2], v[3])))
                    .collect::<Result<Vec<_>, _>>()?;
                Ok((d, extra))
            });
            let (d, extra) = match parsed {
                Ok(v) => v,
                Err(e) => {
                    eprintln!("gharial bench riccati: {e}");
                    std::process::exit(2);
                }
            };
            bench::run(&bench::RiccatiBench {
                dims: (d[0], d[1], d[2]),
                horizons,
                extra,
                threads,
                mu,
                seed,
                budget,
                rounds,
                refine,
            });
        }
    }
}
