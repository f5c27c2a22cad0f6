//! `postflight`: the command-line program. It parses arguments, runs stages
//! and reports; the work itself lives in the stage crates.
//!
//! Exit codes: 0 success (warnings are printed, not fatal); 1 the input or a
//! stage failed (the message says what and how to fix it); 2 bad usage.

mod progress;

use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "postflight",
    version,
    about = "Post-flight inspection pipeline for UAV infrastructure inspection"
)]
struct Cli {
    /// Print only errors and warnings (no progress bars); for batch use.
    #[arg(short, long, global = true)]
    quiet: bool,
    /// More log output (-v info, -vv debug).
    #[arg(short, long, global = true, action = clap::ArgAction::Count)]
    verbose: u8,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Read a ROS 2 MCAP flight recording into a run directory.
    Ingest(IngestArgs),
}

#[derive(Args)]
struct IngestArgs {
    /// The flight recording (ROS 2 MCAP).
    #[arg(long)]
    flight: PathBuf,
    /// Run directory to write (created if missing).
    #[arg(long)]
    out: PathBuf,
    /// ROS camera-calibration YAML, for recordings without CameraInfo.
    #[arg(long, value_name = "FILE")]
    camera_info: Option<PathBuf>,
    /// Image topic to use (repeatable; default: every image topic).
    #[arg(long = "image-topic", value_name = "TOPIC")]
    image_topics: Vec<String>,
    /// Pose topic (PoseStamped, PoseWithCovarianceStamped or Odometry).
    #[arg(long, value_name = "TOPIC")]
    pose_topic: Option<String>,
    /// CameraInfo topic.
    #[arg(long, value_name = "TOPIC")]
    camera_info_topic: Option<String>,
    /// PointCloud2 topic with the SLAM map.
    #[arg(long, value_name = "TOPIC")]
    map_topic: Option<String>,
    /// Body frame the poses describe (default: inferred).
    #[arg(long, value_name = "FRAME")]
    body_frame: Option<String>,
    /// World frame when poses come from /tf (default: the tree's root).
    #[arg(long, value_name = "FRAME")]
    world_frame: Option<String>,
    /// Largest pose gap frames are interpolated across, seconds.
    #[arg(long, default_value_t = 0.25, value_name = "SECONDS")]
    max_pose_gap: f64,
    /// Fail on a truncated recording instead of salvaging it.
    #[arg(long)]
    strict: bool,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    init_logging(cli.verbose);
    match run(&cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(1)
        }
    }
}

fn init_logging(verbose: u8) {
    let default = match verbose {
        0 => "warn",
        1 => "info",
        _ => "debug",
    };
    let filter = tracing_subscriber::EnvFilter::try_from_env("POSTFLIGHT_LOG")
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default));
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_target(false)
        .with_ansi(std::io::stderr().is_terminal())
        .without_time()
        .init();
}

fn run(cli: &Cli) -> anyhow::Result<()> {
    match &cli.command {
        Command::Ingest(args) => ingest(args, cli.quiet),
    }
}

fn ingest(args: &IngestArgs, quiet: bool) -> anyhow::Result<()> {
    if !args.max_pose_gap.is_finite() || args.max_pose_gap <= 0.0 {
        anyhow::bail!("--max-pose-gap must be a positive number of seconds");
    }
    let options = ingest::IngestOptions {
        image_topics: args.image_topics.clone(),
        pose_topic: args.pose_topic.clone(),
        camera_info_topic: args.camera_info_topic.clone(),
        camera_info_file: args.camera_info.clone(),
        map_topic: args.map_topic.clone(),
        body_frame: args.body_frame.clone(),
        world_frame: args.world_frame.clone(),
        max_pose_gap_s: args.max_pose_gap,
        strict: args.strict,
        ..ingest::IngestOptions::new(args.flight.clone(), args.out.clone())
    };
    let mut bar = progress::Bytes::new("ingest", quiet);
    let summary = ingest::ingest(&options, &mut bar)?;
    bar.finish();
    for w in &summary.warnings {
        tracing::warn!("{w}");
    }
    if !quiet {
        println!(
            "ingested {} frames ({} with pose), {} poses, {:.1} s of flight{} into {}",
            summary.frames,
            summary.frames_with_pose,
            summary.poses,
            summary.duration_s,
            if summary.truncated {
                " (TRUNCATED recording, salvaged)"
            } else {
                ""
            },
            args.out.display()
        );
    }
    Ok(())
}
