//! `postflight review`: serve the review queue of a run, and export its
//! decisions.

use std::net::SocketAddr;
use std::path::PathBuf;

use clap::{Args, Subcommand};
use review::ServeOptions;

#[derive(Subcommand)]
pub enum ReviewCommand {
    /// Serve the review queue in the browser: inspectors accept, reject or
    /// mark for repair each defect candidate (decisions kept in SQLite).
    Serve(ServeArgs),
    /// Write the decisions (review-decisions.csv/.json) and the accepted
    /// defects (accepted-defects.csv/.parquet).
    Export(ExportArgs),
}

#[derive(Args)]
pub struct ServeArgs {
    /// Run directory holding a completed localise stage.
    #[arg(long)]
    run: PathBuf,
    /// Decisions database (SQLite; created if missing) [default: RUN/review.sqlite].
    #[arg(long, value_name = "FILE")]
    db: Option<PathBuf>,
    /// Address to listen on. Anything but loopback requires an access token.
    #[arg(long, default_value = postflight_core::outputs::report::DEFAULT_REVIEW_ADDR)]
    addr: SocketAddr,
    /// Access token (at least 16 letters, digits, '-' or '_') [default:
    /// none on loopback, generated otherwise].
    #[arg(long, env = "POSTFLIGHT_REVIEW_TOKEN", hide_env_values = true)]
    token: Option<String>,
}

#[derive(Args)]
pub struct ExportArgs {
    /// Run directory holding a completed localise stage.
    #[arg(long)]
    run: PathBuf,
    /// Decisions database [default: RUN/review.sqlite].
    #[arg(long, value_name = "FILE")]
    db: Option<PathBuf>,
    /// Directory to write into [default: RUN].
    #[arg(long)]
    out: Option<PathBuf>,
}

fn db_path(run: &std::path::Path, db: &Option<PathBuf>) -> PathBuf {
    db.clone()
        .unwrap_or_else(|| run.join(review::store::DEFAULT_DB))
}

pub fn run(command: &ReviewCommand, quiet: bool) -> anyhow::Result<()> {
    match command {
        ReviewCommand::Serve(args) => {
            let options = ServeOptions {
                db: db_path(&args.run, &args.db),
                run: args.run.clone(),
                addr: args.addr,
                token: args.token.clone(),
            };
            let db = options.db.clone();
            review::serve(options, |l| {
                // The address is printed even with -q: it is the output.
                println!("review queue: {}", l.url);
                if !quiet {
                    println!(
                        "{} candidates ({} new), {} decided; decisions in {}; Ctrl-C stops (every decision is saved as it is made)",
                        l.candidates,
                        l.new,
                        l.decided,
                        db.display()
                    );
                    if l.token_generated {
                        println!(
                            "listening beyond loopback: the access token was generated and is in the address above; anyone with that address can decide"
                        );
                    }
                }
            })?;
            Ok(())
        }
        ReviewCommand::Export(args) => {
            let out = args.out.clone().unwrap_or_else(|| args.run.clone());
            let written =
                review::export::export_run(&args.run, &db_path(&args.run, &args.db), &out)?;
            if !quiet {
                for path in written {
                    println!("wrote {}", path.display());
                }
            }
            Ok(())
        }
    }
}
