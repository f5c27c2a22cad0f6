//! `postflight`: the command-line program. It parses arguments, runs stages
//! and reports; the work itself lives in the stage crates.
//!
//! Exit codes: 0 success (warnings are printed, not fatal); 1 the input or a
//! stage failed (the message says what and how to fix it); 2 bad usage.

mod batch;
mod config;
mod demo;
mod help;
mod pipeline;
mod progress;
mod review;
mod stages;
mod wording;

use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, CommandFactory, FromArgMatches, Parser, Subcommand};
use postflight_core::{PlanFile, Stage, YawUnit};

use crate::config::RunConfig;

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
    /// Run the whole pipeline on a flight (ingest, detect, localise,
    /// coverage, replan, report); re-runs skip stages whose inputs and
    /// settings are unchanged, so an interrupted run resumes.
    Run(RunArgs),
    /// Simulate the default bridge flight and run the whole pipeline on it
    /// with the reference crack detector shipped inside postflight.
    Demo(DemoArgs),
    /// Read a flight recording (MCAP with ROS 2 or ROS 1 messages, or a ROS 1 bag) into a run directory.
    Ingest(IngestArgs),
    /// Simulate an inspection flight with ground truth (flight.mcap, map.ply,
    /// plan.json, truth.json).
    Simulate(sim::SimOptions),
    /// Run the crack detector (ONNX) over an ingested run's frames: on the
    /// tiles that show each patch of the structure in its best views (or
    /// every tile), or on a share of the flight.
    Detect(DetectArgs),
    /// Place each detection on the SLAM map and fuse views into defect candidates.
    Localise(LocaliseArgs),
    /// Recompute voxel coverage achieved versus planned under the View model.
    Coverage(CoverageArgs),
    /// Plan a follow-up flight for the coverage gaps (GTSP over candidate
    /// viewpoints, collision-checked paths); writes replan.json and replan.csv.
    Replan(ReplanArgs),
    /// Solve a Generalized TSP instance (GTSPLIB, GLNS or Karapetyan format);
    /// prints {"instance", "cost", "tour", "time_s", "stats"} as JSON.
    Gtsp(GtspArgs),
    /// The element record a bridge owner submits: each AASHTO element's
    /// quantities in condition states 1-4 and its cracking defect's, from
    /// the candidates, the coverage and the reviewers' decisions; writes
    /// elements.parquet, nbe.xml, snbi-elements.json and record.json.
    Record(RecordArgs),
    /// Write summary.json and the self-contained report.html of a run directory.
    Report(ReportArgs),
    /// The human review queue: inspectors accept or reject each defect candidate.
    #[command(subcommand)]
    Review(review::ReviewCommand),
    /// Many flights from a manifest: run them here or on Slurm, follow
    /// them, or write a Kubernetes Job for them.
    #[command(subcommand)]
    Batch(batch::BatchCommand),
    /// What changed since an earlier inspection of the same structure:
    /// registers the two flights' maps and classifies every defect candidate
    /// (new, first seen, grown, widened, unchanged, not seen again, not
    /// re-inspected); writes changes.json and changes.parquet into the later
    /// run.
    Compare(CompareArgs),
    /// Write a fleet directory's tables (fleet/defects.parquet,
    /// coverage.parquet, flights.parquet; Hive-partitioned by structure) and
    /// fleet/index.html linking every flight's report.
    Fleet(FleetDirArgs),
}

#[derive(Args)]
struct CompareArgs {
    /// The earlier run directory (localised).
    #[arg(long, value_name = "RUN_A")]
    before: PathBuf,
    /// The later run directory (with coverage); the results go here.
    #[arg(long, value_name = "RUN_B")]
    after: PathBuf,
    #[command(flatten)]
    settings: compare::CompareSettings,
    #[command(flatten)]
    config: config::ConfigArg,
}

#[derive(Args)]
struct FleetDirArgs {
    /// The fleet directory (`postflight batch run --out`).
    fleet_dir: PathBuf,
}

/// The flight's recordings and photo folders.
#[derive(Args)]
struct FlightArgs {
    /// A flight recording: MCAP (ROS 2 or ROS 1 messages) or a ROS 1 bag
    /// (.bag). Repeat it for a flight recorded in several sorties or by
    /// several drones (--flight A.mcap --flight B.mcap), or give a
    /// directory: its .mcap and .bag files in name order, else its photos
    /// (a photo folder), else its folders of photos (one per sortie).
    #[arg(
        long = "flight",
        required_unless_present = "photos",
        value_name = "RECORDING"
    )]
    flights: Vec<PathBuf>,
    /// A folder of geotagged photos (JPEG with EXIF GPS; DJI's XMP gimbal
    /// angles, lens and RTK tags), one per sortie; repeatable.
    #[arg(long = "photos", value_name = "DIR")]
    photos: Vec<PathBuf>,
}

impl FlightArgs {
    /// Every recording and photo folder given, directories listed.
    fn recordings(&self) -> anyhow::Result<Vec<PathBuf>> {
        let mut all = Vec::new();
        for path in &self.flights {
            all.extend(ingest::sources_in(path)?);
        }
        for folder in &self.photos {
            ingest::PhotoFolder::open(folder)?;
            all.push(folder.clone());
        }
        Ok(all)
    }
}

/// `--map`, as every command that reads the map takes it.
#[derive(clap::Args, Debug, Clone)]
struct MapArg {
    /// Map: PLY, PCD, OctoMap .bt/.ot, an OBJ or PLY mesh (world frame, metres),
    /// or a LAS/LAZ in its CRS; instead of the one recorded in the flight
    /// (for replan, the one coverage used).
    #[arg(long = "map", value_name = "FILE")]
    file: Option<PathBuf>,
}

#[derive(Args)]
struct RunArgs {
    #[command(flatten)]
    flight: FlightArgs,
    #[command(flatten)]
    map: MapArg,
    #[command(flatten)]
    plan: PlanArgs,
    #[command(flatten)]
    targets: TargetArgs,
    /// Crack detector exported to ONNX: YOLO-World (either interface), a
    /// YOLO detection or -seg model, or a semantic segmenter; its input
    /// convention from [detect] or its metadata [default: the reference
    /// detector for simulated flights].
    #[arg(long, value_name = "M.onnx")]
    model: Option<PathBuf>,
    #[command(flatten)]
    config: config::ConfigArg,
    /// ONNX Runtime library (default: ORT_DYLIB_PATH, the project .venv, python3's onnxruntime).
    #[arg(long, value_name = "PATH")]
    onnxruntime: Option<PathBuf>,
    /// Run directory (created if missing; a previous run there is resumed).
    #[arg(long)]
    out: PathBuf,
    /// Rerun from this stage on, even if it is up to date.
    #[arg(long, value_enum, value_name = "STAGE")]
    force: Option<Stage>,
    #[command(flatten)]
    previous: PreviousArg,
}

#[derive(Args)]
struct DemoArgs {
    /// Directory for the simulated flight, the model and the run.
    #[arg(long, default_value = "demo-run")]
    out: PathBuf,
    /// Rerun from this stage on, even if it is up to date.
    #[arg(long, value_enum, value_name = "STAGE")]
    force: Option<Stage>,
}

#[derive(Args)]
struct RecordArgs {
    /// Run directory holding a completed coverage (and localise); its
    /// review.sqlite holds the decisions.
    #[arg(long)]
    run: PathBuf,
    #[command(flatten)]
    previous: PreviousArg,
    #[command(flatten)]
    settings: record::RecordSettings,
    #[command(flatten)]
    config: config::ConfigArg,
}

/// `--previous`: an earlier record of the structure.
#[derive(Args)]
struct PreviousArg {
    /// An earlier run of the same structure with a record (elements.parquet):
    /// with [record] not_inspected = "previous", what this flight missed
    /// takes its states.
    #[arg(long, value_name = "RUN")]
    previous: Option<PathBuf>,
}

#[derive(Args)]
struct ReportArgs {
    /// Run directory (at least ingested).
    #[arg(long)]
    run: PathBuf,
}

#[derive(Args)]
struct GtspArgs {
    /// Instance file.
    instance: PathBuf,
    /// Wall-clock bound in seconds; the best tour so far is returned.
    #[arg(long, value_name = "S")]
    time_limit: Option<f64>,
    /// Random seed; a seed and thread count give the same tour when the
    /// search ends before the time limit.
    #[arg(long, default_value_t = gtsp::SolveOptions::default().seed)]
    seed: u64,
    /// Worker threads (0: one per core).
    #[arg(long, default_value_t = 0)]
    threads: usize,
}

#[derive(Args)]
struct ReplanArgs {
    /// Run directory holding a completed coverage stage.
    #[arg(long)]
    run: PathBuf,
    #[command(flatten)]
    map: MapArg,
    #[command(flatten)]
    settings: replan::ReplanSettings,
    #[command(flatten)]
    config: config::ConfigArg,
}

/// The plan that was flown.
#[derive(Args)]
struct PlanArgs {
    /// The inspection plan that was flown: postflight's plan.json, or a
    /// waypoint path X,Y,Z,Yaw (.csv, GATSBI's; its targets from a --target-* option).
    #[arg(long, value_name = "plan.json|path.csv")]
    plan: Option<PathBuf>,
    /// The yaws of a waypoint path are in degrees, not radians.
    #[arg(long)]
    yaw_degrees: bool,
}

impl PlanArgs {
    fn file(&self, path: Option<&PathBuf>) -> Option<PlanFile> {
        let yaw = if self.yaw_degrees {
            YawUnit::Degrees
        } else {
            YawUnit::Radians
        };
        path.map(|path| PlanFile {
            path: path.clone(),
            yaw,
        })
    }

    fn plan(&self) -> Option<PlanFile> {
        self.file(self.plan.as_ref())
    }
}

/// Where the structure to inspect comes from, instead of a plan's target voxels.
#[derive(Args)]
#[group(multiple = false)]
struct TargetArgs {
    /// Targets: occupied map voxels inside these boxes (JSON list of {"min": [x,y,z], "max": [x,y,z]}).
    #[arg(long, value_name = "FILE")]
    target_boxes: Option<PathBuf>,
    /// Targets: voxels of a segmented infrastructure cloud (PLY, PCD).
    #[arg(long, value_name = "FILE")]
    target_cloud: Option<PathBuf>,
    /// Targets: occupied voxels of a segmented OctoMap (.bt, .ot), as GATSBI segments its structure.
    #[arg(long, value_name = "FILE")]
    target_map: Option<PathBuf>,
}

impl TargetArgs {
    fn targets(&self) -> coverage::Targets {
        match (&self.target_boxes, &self.target_cloud, &self.target_map) {
            (Some(path), _, _) => coverage::Targets::Boxes(path.clone()),
            (_, Some(path), _) | (_, _, Some(path)) => coverage::Targets::Cloud(path.clone()),
            _ => coverage::Targets::Plan,
        }
    }
}

#[derive(Args)]
struct CoverageArgs {
    /// Run directory holding a completed ingest.
    #[arg(long)]
    run: PathBuf,
    #[command(flatten)]
    plan: PlanArgs,
    /// Judge this plan's viewpoints instead of the flight's frames (check a plan before flying it).
    #[arg(long, value_name = "plan.json|path.csv")]
    viewpoints: Option<PathBuf>,
    /// Judge the viewpoints as shots of this camera (a ROS camera_info YAML: a team drone's) instead of the flight's.
    #[arg(long, value_name = "camera.yaml", requires = "viewpoints")]
    viewpoint_camera: Option<PathBuf>,
    #[command(flatten)]
    map: MapArg,
    #[command(flatten)]
    targets: TargetArgs,
    #[command(flatten)]
    view: postflight_core::ViewSettings,
    #[command(flatten)]
    settings: coverage::CoverageSettings,
    #[command(flatten)]
    config: config::ConfigArg,
}

#[derive(Args)]
struct LocaliseArgs {
    /// Run directory holding a completed detect.
    #[arg(long)]
    run: PathBuf,
    #[command(flatten)]
    map: MapArg,
    /// Inspection plan: its target voxels are the structure (hits elsewhere are obstacles).
    #[arg(long, value_name = "plan.json")]
    plan: Option<PathBuf>,
    /// The structure whose elements name each candidate's place, instead
    /// of the plan's target voxels.
    #[command(flatten)]
    targets: TargetArgs,
    #[command(flatten)]
    settings: localise::LocaliseSettings,
    /// Each view is judged by the View model, as coverage judges it.
    #[command(flatten)]
    view: postflight_core::ViewSettings,
    #[command(flatten)]
    condition: postflight_core::condition::ConditionSettings,
    #[command(flatten)]
    config: config::ConfigArg,
}

#[derive(Args)]
struct DetectArgs {
    /// Run directory holding a completed ingest.
    #[arg(long)]
    run: PathBuf,
    /// Run only share K of N of the flight's frames (each holding about an
    /// Nth of the tiles to run), written beside the others as
    /// detect-shard-K-of-N.*; `--merge` (or localise) puts them together.
    #[arg(long, value_name = "K/N", conflicts_with = "merge")]
    shard: Option<postflight_core::outputs::detect::Shard>,
    /// Merge the shares written by `--shard` into the flight's detections.
    #[arg(long)]
    merge: bool,
    /// The map the best views of each patch are chosen by
    /// (`[detect] views_per_patch`).
    #[command(flatten)]
    map: MapArg,
    /// Inspection plan: its target voxels are the patches whose best views
    /// run, on its voxel grid, judged by its View model.
    #[arg(long, value_name = "plan.json")]
    plan: Option<PathBuf>,
    /// Each view of a patch is judged by the View model, as localise
    /// judges it.
    #[command(flatten)]
    view: postflight_core::ViewSettings,
    /// Crack detector exported to ONNX: YOLO-World (either interface), a
    /// YOLO detection or -seg model, or a semantic segmenter (one map of
    /// crack probability or logits); see --channel-order, --pixel-scale,
    /// --mean and --std for its input convention.
    #[arg(long, required_unless_present = "merge")]
    model: Option<PathBuf>,
    /// ONNX Runtime library (default: ORT_DYLIB_PATH, the project .venv, python3's onnxruntime).
    #[arg(long, value_name = "PATH")]
    onnxruntime: Option<PathBuf>,
    #[command(flatten)]
    settings: detect::DetectSettings,
    #[command(flatten)]
    config: config::ConfigArg,
}

#[derive(Args)]
struct IngestArgs {
    #[command(flatten)]
    flight: FlightArgs,
    /// Run directory to write (created if missing).
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    settings: ingest::IngestSettings,
    #[command(flatten)]
    config: config::ConfigArg,
}

fn main() -> ExitCode {
    let matches = help::with_defaults(Cli::command()).get_matches();
    let cli = match Cli::from_arg_matches(&matches) {
        Ok(cli) => cli,
        Err(e) => e.exit(),
    };
    init_logging(cli.verbose);
    word_settings(&cli, &matches);
    match run(&cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(1)
        }
    }
}

/// Word settings in errors as this command line and its config file gave them.
fn word_settings(cli: &Cli, matches: &clap::ArgMatches) {
    let mut sources = wording::Sources::of(matches);
    if let Command::Batch(_) = &cli.command {
        sources = sources.with_config_source("a config file (the manifest's `config` column)");
    }
    // An unreadable config file is reported when the command reads it.
    let config = config_file(&cli.command)
        .and_then(|path| config::RunConfig::load(&path).ok().map(|c| (path, c)));
    if let Some((path, config)) = config {
        sources = sources.with_config(&path, &config);
    }
    sources.install();
}

/// The config file the command reads, if any.
fn config_file(command: &Command) -> Option<PathBuf> {
    let arg = match command {
        Command::Run(args) => &args.config,
        Command::Ingest(args) => &args.config,
        Command::Detect(args) => &args.config,
        Command::Localise(args) => &args.config,
        Command::Coverage(args) => &args.config,
        Command::Replan(args) => &args.config,
        Command::Record(args) => &args.config,
        Command::Compare(args) => &args.config,
        Command::Batch(command) => return batch::task_config(command),
        _ => return None,
    };
    arg.config.clone()
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
        Command::Simulate(options) => stages::simulate(options, cli.quiet),
        Command::Detect(args) => detect(args, cli.quiet),
        Command::Localise(args) => localise(args, cli.quiet),
        Command::Coverage(args) => coverage(args, cli.quiet),
        Command::Replan(args) => replan(args, cli.quiet),
        Command::Gtsp(args) => gtsp(args),
        Command::Record(args) => record(args, cli.quiet),
        Command::Report(args) => report(args, cli.quiet),
        Command::Review(command) => review::run(command, cli.quiet),
        Command::Run(args) => run_pipeline(args, cli.quiet),
        Command::Demo(args) => demo::demo(&args.out, args.force, cli.quiet),
        Command::Batch(command) => batch::run(command, cli.quiet),
        Command::Fleet(args) => batch::fleet_tables(&args.fleet_dir, cli.quiet),
        Command::Compare(args) => compare(args, cli.quiet),
    }
}

fn ingest(args: &IngestArgs, quiet: bool) -> anyhow::Result<()> {
    let flags = RunConfig {
        ingest: args.settings.clone(),
        ..RunConfig::default()
    };
    let config = args.config.under(flags)?;
    let recordings = args.flight.recordings()?;
    stages::ingest(&config.ingest_options(&recordings, &args.out), quiet)
}

fn detect(args: &DetectArgs, quiet: bool) -> anyhow::Result<()> {
    let Some(model) = args.model.as_deref().filter(|_| !args.merge) else {
        return stages::merge(&args.run, quiet).map(drop);
    };
    let flags = RunConfig {
        detect: args.settings.clone(),
        view: args.view,
        ..RunConfig::default()
    };
    let config = args.config.under(flags)?;
    let plan = args.plan.clone().map(PlanFile::new);
    let mut options = config.detect_options(
        &args.run,
        model,
        args.onnxruntime.as_deref(),
        args.map.file.as_deref(),
        plan.as_ref(),
    );
    options.shard = args.shard;
    stages::detect(&options, quiet)
}

fn localise(args: &LocaliseArgs, quiet: bool) -> anyhow::Result<()> {
    if let Some(path) = args.plan.as_ref().filter(|p| PlanFile::new(*p).is_path()) {
        anyhow::bail!(
            "--plan {}: a waypoint path names no structure voxels, which is all localise takes from a plan; give the plan.json, or leave --plan out",
            path.display()
        );
    }
    let flags = RunConfig {
        localise: args.settings.clone(),
        view: args.view,
        condition: args.condition,
        ..RunConfig::default()
    };
    let config = args.config.under(flags)?;
    let plan = args.plan.clone().map(PlanFile::new);
    let options = config.localise_options(
        &args.run,
        args.map.file.as_deref(),
        plan.as_ref(),
        args.targets.targets(),
    );
    stages::localise(&options, quiet)
}

fn coverage(args: &CoverageArgs, quiet: bool) -> anyhow::Result<()> {
    let flags = RunConfig {
        view: args.view,
        coverage: args.settings.clone(),
        ..RunConfig::default()
    };
    let config = args.config.under(flags)?;
    let options = coverage::CoverageOptions {
        viewpoints: args.plan.file(args.viewpoints.as_ref()),
        viewpoint_camera: args.viewpoint_camera.clone(),
        ..config.coverage_options(
            &args.run,
            args.map.file.as_deref(),
            args.plan.plan().as_ref(),
            args.targets.targets(),
        )
    };
    stages::coverage(&options, quiet)
}

fn record(args: &RecordArgs, quiet: bool) -> anyhow::Result<()> {
    let config = args.config.under(RunConfig {
        record: args.settings.clone(),
        ..RunConfig::default()
    })?;
    let options = config.record_options(&args.run, args.previous.previous.as_deref())?;
    stages::record(&options, quiet)
}

fn replan(args: &ReplanArgs, quiet: bool) -> anyhow::Result<()> {
    let flags = RunConfig {
        replan: args.settings.clone(),
        ..RunConfig::default()
    };
    let config = args.config.under(flags)?;
    stages::replan(
        &config.replan_options(&args.run, args.map.file.as_deref()),
        quiet,
    )
}

fn report(args: &ReportArgs, quiet: bool) -> anyhow::Result<()> {
    let options = reports::ReportOptions {
        run: args.run.clone(),
    };
    stages::report(&options, quiet)
}

fn run_pipeline(args: &RunArgs, quiet: bool) -> anyhow::Result<()> {
    let config = args.config.under(RunConfig::default())?;
    let inputs = pipeline::RunInputs {
        flights: args.flight.recordings()?,
        map: args.map.file.clone(),
        plan: args.plan.plan(),
        targets: args.targets.targets(),
        model: args.model.clone(),
        onnxruntime: args.onnxruntime.clone(),
        config,
        out: args.out.clone(),
        force: args.force,
        previous: args.previous.previous.clone(),
    };
    pipeline::run(&inputs, quiet)?;
    if !quiet {
        println!(
            "run complete: {}",
            args.out
                .join(postflight_core::outputs::report::files::REPORT)
                .display()
        );
    }
    Ok(())
}

fn compare(args: &CompareArgs, quiet: bool) -> anyhow::Result<()> {
    let config = args.config.under(RunConfig {
        compare: args.settings.clone(),
        ..RunConfig::default()
    })?;
    let options = compare::CompareOptions {
        settings: config.compare.resolve(),
        ..compare::CompareOptions::new(args.before.clone(), args.after.clone())
    };
    let summary = compare::compare(&options)?;
    // The later run's report gets its "changes since" section.
    if postflight_core::RunDir::open(&args.after, Stage::Report).is_ok() {
        stages::report(
            &reports::ReportOptions {
                run: args.after.clone(),
            },
            quiet,
        )?;
    }
    if !quiet {
        let r = &summary.registration;
        let t = r.transform.translation;
        println!(
            "registered: shift {:.3}, {:.3}, {:.3} m, yaw {:.2} deg; residual {:.3} m RMS over {:.0}% of the earlier map",
            t[0], t[1], t[2], r.yaw_deg, r.rms_m, r.overlap_pct
        );
        let counts: Vec<String> = postflight_core::outputs::changes::ChangeKind::ALL
            .iter()
            .map(|k| (summary.count(*k), k.words()))
            .filter(|(n, _)| *n > 0)
            .map(|(n, k)| format!("{n} {k}"))
            .collect();
        println!(
            "changes since {}: {}; written to {}",
            summary.before_date(),
            counts.join(", "),
            args.after
                .join(postflight_core::outputs::changes::files::SUMMARY)
                .display()
        );
        for line in summary.elements.iter().flat_map(|e| e.moved()) {
            println!("  {line}");
        }
    }
    Ok(())
}

fn gtsp(args: &GtspArgs) -> anyhow::Result<()> {
    use gtsp::{Instance, SolveOptions, solve};
    let time_limit = match args.time_limit {
        Some(s) if s.is_finite() && s > 0.0 => Some(std::time::Duration::from_secs_f64(s)),
        Some(s) => anyhow::bail!("--time-limit must be a positive number of seconds, not {s}"),
        None => None,
    };
    let inst = Instance::read(&args.instance)
        .map_err(|e| anyhow::anyhow!("{}: {e}", args.instance.display()))?;
    let options = SolveOptions {
        time_limit,
        seed: args.seed,
        threads: args.threads,
        ..SolveOptions::default()
    };
    let solution = solve(&inst, &options);
    let tour: Vec<u32> = solution.tour.iter().map(|v| v + 1).collect();
    let out = serde_json::json!({
        "instance": inst.name,
        "cost": solution.cost,
        "tour": tour,
        "time_s": solution.stats.time_s,
        "stats": solution.stats,
    });
    println!("{out}");
    Ok(())
}
