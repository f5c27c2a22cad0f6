//! `postflight.toml`: settings for every stage, one table per stage, every
//! key optional; unknown tables and keys are refused. Each table is a stage
//! crate's settings struct (declared once with `postflight_core::settings!`),
//! which also gives the stage command its flags. Every stage command and
//! `postflight run` layer them the same way: defaults < `--config` file <
//! flags.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use clap::Args;
use postflight_core::condition::ConditionSettings;
use postflight_core::{PlanFile, ViewSettings};
use serde::{Deserialize, Serialize};

use crate::stages;

/// The tables of `postflight.toml`, each named once: in the order of its
/// documentation, each a stage crate's settings (`postflight_core::settings!`),
/// and where an unset key's value comes from before its default. Gives
/// [`RunConfig`], [`ConfigArg`], [`tables`], [`RunConfig::over`] and the
/// list the errors name.
macro_rules! stage_tables {
    ($( $table:ident: $settings:ty $(, default from $from:literal)?; )+) => {
        /// The settings of every stage: `postflight.toml`, or the flags of one
        /// command (where only that stage's tables are set).
        #[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
        #[serde(default, deny_unknown_fields)]
        pub struct RunConfig {
            $( pub $table: $settings, )+
        }

        /// `--config`: the file a stage command reads its tables from.
        #[derive(Debug, Clone, Default, Args)]
        pub struct ConfigArg {
            #[arg(
                long,
                value_name = "postflight.toml",
                help = concat!("Settings file (postflight.toml; tables", $(" [", stringify!($table), "]",)+ "); flags given win over it")
            )]
            pub config: Option<PathBuf>,
        }

        /// Every table, in the order of `postflight.toml`'s documentation.
        pub fn tables() -> Vec<Table> {
            vec![$(
                Table {
                    name: <$settings>::TABLE,
                    args: <$settings>::augment_args(clap::Command::new(<$settings>::TABLE)),
                    defaults: serde_json::to_value(<$settings>::default().resolve())
                        .expect("defaults serialise to JSON"),
                    default_from: None $(.or(Some($from)))?,
                },
            )+]
        }

        impl RunConfig {
            /// Each setting from `self` where set, else from `under`.
            pub fn over(&self, under: &Self) -> Self {
                Self {
                    $( $table: self.$table.over(&under.$table), )+
                }
            }
        }

        /// The tables, as errors list them.
        const TABLE_LIST: &str = concat!($("[", stringify!($table), "] ",)+);
    };
}

stage_tables! {
    ingest: ingest::IngestSettings;
    detect: detect::DetectSettings;
    localise: localise::LocaliseSettings;
    view: ViewSettings, default from "the plan's, else";
    condition: ConditionSettings;
    coverage: coverage::CoverageSettings;
    replan: replan::ReplanSettings;
    record: record::RecordSettings;
    compare: compare::CompareSettings;
}

impl ConfigArg {
    /// The file's settings with `flags` over them.
    pub fn under(&self, flags: RunConfig) -> anyhow::Result<RunConfig> {
        Ok(flags.over(&RunConfig::load_or_default(self.config.as_deref())?))
    }
}

/// One table of `postflight.toml`, as the command line sees it.
pub struct Table {
    /// Its name in `postflight.toml`.
    pub name: &'static str,
    /// Its flags (each argument's id is its key).
    pub args: clap::Command,
    /// Each key's default, where it has one (JSON null where it has none).
    pub defaults: serde_json::Value,
    /// Where an unset key's value comes from before its default.
    pub default_from: Option<&'static str>,
}

impl RunConfig {
    /// Every `(table, key)` of the file, set or not (JSON keeps unset
    /// keys as null, where TOML leaves them out).
    #[cfg(test)]
    pub fn keys(&self) -> BTreeSet<(String, String)> {
        let value = serde_json::to_value(self).expect("the config serialises to JSON");
        let tables = value.as_object().into_iter().flatten();
        tables
            .flat_map(|(table, keys)| {
                keys.as_object()
                    .into_iter()
                    .flatten()
                    .map(move |(key, _)| (table.clone(), key.clone()))
            })
            .collect()
    }

    /// The `(table, key)`s this file sets.
    pub fn keys_set(&self) -> BTreeSet<(String, String)> {
        // Through TOML, not JSON: JSON has no NaN or infinity, and a key
        // set to one would read as unset (and be worded as its flag).
        let value = toml::Value::try_from(self).expect("the config serialises to TOML");
        let tables = value.as_table().into_iter().flatten();
        tables
            .flat_map(|(table, keys)| {
                keys.as_table()
                    .into_iter()
                    .flatten()
                    .map(move |(key, _)| (table.clone(), key.clone()))
            })
            .collect()
    }

    /// The file at `path`, or every setting unset without one.
    pub fn load_or_default(path: Option<&Path>) -> anyhow::Result<Self> {
        path.map_or_else(|| Ok(Self::default()), Self::load)
    }

    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let text = postflight_core::user_file::read_to_string(path)
            .map_err(|e| anyhow::anyhow!("cannot read config {}: {e}", path.display()))?;
        Self::parse(&text).map_err(|why| anyhow::anyhow!("config {}: {why}", path.display()))
    }

    /// A `postflight.toml`'s text, or a one-line error naming the line and
    /// column.
    pub fn parse(text: &str) -> Result<Self, String> {
        toml::from_str(text).map_err(|e| {
            format!(
                "{}; the tables are {}(see docs/cli.md)",
                e.to_string().trim().replace('\n', " "),
                TABLE_LIST
            )
        })
    }

    pub fn ingest_options(&self, flights: &[PathBuf], out: &Path) -> ingest::IngestOptions {
        ingest::IngestOptions {
            settings: self.ingest.resolve(),
            ..ingest::IngestOptions::new(flights.to_vec(), out.to_owned())
        }
    }

    /// Detect's options, and what it chooses the tiles to run by: the
    /// map (the given one, else the flight's) on the plan's grid, judged
    /// by the View model.
    pub fn detect_options(
        &self,
        run: &Path,
        model: &Path,
        onnxruntime: Option<&Path>,
        map: Option<&Path>,
        plan: Option<&PlanFile>,
    ) -> stages::DetectRun {
        stages::DetectRun {
            detect: detect::DetectOptions {
                onnxruntime: onnxruntime.map(Path::to_path_buf),
                settings: self.detect.resolve(),
                ..detect::DetectOptions::new(run.to_owned(), model.to_owned())
            },
            map: map.map(Path::to_path_buf),
            plan: plan.cloned(),
            view: self.view,
            shard: None,
        }
    }

    pub fn localise_options(
        &self,
        run: &Path,
        map: Option<&Path>,
        plan: Option<&PlanFile>,
        targets: coverage::Targets,
    ) -> localise::LocaliseOptions {
        localise::LocaliseOptions {
            map: map.map(Path::to_path_buf),
            plan: plan.cloned(),
            targets,
            settings: self.localise.resolve(),
            view: self.view,
            condition: self.condition,
            ..localise::LocaliseOptions::new(run.to_owned())
        }
    }

    pub fn coverage_options(
        &self,
        run: &Path,
        map: Option<&Path>,
        plan: Option<&PlanFile>,
        targets: coverage::Targets,
    ) -> coverage::CoverageOptions {
        coverage::CoverageOptions {
            plan: plan.cloned(),
            map: map.map(Path::to_path_buf),
            targets,
            view: self.view,
            settings: self.coverage.resolve(),
            ..coverage::CoverageOptions::new(run.to_owned())
        }
    }

    /// The record's options: the run's `review.sqlite` holds the decisions.
    pub fn record_options(
        &self,
        run: &Path,
        previous: Option<&Path>,
    ) -> anyhow::Result<record::RecordOptions> {
        let db = run.join(review::store::DEFAULT_DB);
        Ok(record::RecordOptions {
            settings: self.record.resolve(),
            condition: self.condition.resolve(),
            previous: previous.map(Path::to_path_buf),
            decisions: review::store::record_decisions(&db)?,
            ..record::RecordOptions::new(run.to_owned())
        })
    }

    pub fn replan_options(&self, run: &Path, map: Option<&Path>) -> replan::ReplanOptions {
        replan::ReplanOptions {
            map: map.map(Path::to_path_buf),
            settings: self.replan.resolve(),
            ..replan::ReplanOptions::new(run.to_owned())
        }
    }
}

/// A `postflight.toml` setting every key of every table, each to a value
/// other than its default.
#[cfg(test)]
pub const FULL: &str = r#"
[ingest]
image_topics = ["/camera/image_raw"]
pose_topic = "/lio_sam/mapping/odometry"
camera_info_topic = "/camera/camera_info"
camera_info_file = "camera.yaml"
map_topic = "/lio_sam/mapping/map_global"
body_frame = "base_link"
world_frame = "map"
max_pose_gap_s = 0.5
photo_origin = [47.397742, 8.545594, 488.0]
reconstruction = "odm/opensfm/reconstruction.json"
strict = true
[[ingest.recording_frame]]
recording = "drone-2.mcap"
origin = [12.0, -3.0, 0.0, 90.0]
[detect]
prompts = ["crack", "spalling"]
class_kinds = ["spalling=spall"]
area_model = "area-unet.onnx"
embeddings = "embeddings.json"
confidence = 0.3
iou = 0.6
merge_gap = 8.0
image_size = 960
tile = 640
tile_overlap = 0.25
views_per_patch = 3
batch = 2
channel_order = "bgr"
pixel_scale = 255.0
mean = [0.485, 0.456, 0.406]
std = [0.229, 0.224, 0.225]
device = "cuda"
[localise]
max_range_m = 25.0
link_distance_m = 0.3
max_normal_angle_deg = 25.0
length_range_m = 6.0
crack_darkness = 0.7
camera_blur_px = 1.2
[view]
cone_apex_deg = 25.0
min_distance_m = 1.5
max_distance_m = 4.0
max_incidence_deg = 55.0
max_blur_px = 2.0
max_gsd_mm = 5.0
views_required = 2
[condition]
material = "prestressed_concrete"
insignificant_below_mm = 0.2
wide_above_mm = 1.0
[coverage]
views_near_defects = 3
defect_radius_m = 1.5
exposure_s = 0.002
[[coverage.focus]]
region = { name = "east bearing", outline = [[7.2, -2.7], [8.8, -2.7], [8.8, 2.7], [7.2, 2.7]], top_m = 5.0 }
view = { max_gsd_mm = 3.0, views_required = 2 }
[replan]
home = [0.0, 0.0, 0.0]
clearance_m = 1.2
max_sortie_length_m = 800.0
battery_minutes = 20.0
gaps = "all"
speed_m_s = 3.0
hover_s = 1.0
solver_time_limit_s = 5.0
drones = 2
seed = 7
geo_origin = [47.397742, 8.545594, 488.0, 23.5]
max_gimbal_up_deg = 35.0
dji_aircraft = "m350-h20t"
keep_out_file = "zones.geojson"
ceiling_m = 40.0
[[replan.drone]]
name = "zoom"
[[replan.drone]]
name = "wide"
home = [12.0, -12.0, 1.0]
speed_m_s = 3.0
battery_minutes = 30.0
camera_info_file = "wide.yaml"
[[replan.keep_out]]
name = "carriageway"
outline = [[0.0, -4.5], [16.0, -4.5], [16.0, 4.5], [0.0, 4.5]]
bottom_m = 6.5
[record]
structure_number = "000000000012345"
state_code = "06"
cell_m = 0.5
not_inspected = "cs1"
min_inspected_pct = 90.0
pending = "skip"
[[record.element]]
name = "deck"
number = 38
quantity = 210.0
[compare]
link_distance_m = 0.15
"#;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_every_table_and_rejects_unknown_keys() {
        let c: RunConfig = toml::from_str(
            "[detect]\nconfidence = 0.4\ndevice = \"cuda\"\n[view]\nmax_distance_m = 6.0\n[replan]\nclearance_m = 1.5\nhome = [0.0, 1.0, 2.0]\n",
        )
        .unwrap();
        assert_eq!(c.detect.confidence, Some(0.4));
        assert_eq!(c.detect.device, Some(detect::Device::Cuda));
        assert_eq!(c.view.max_distance_m, Some(6.0));
        let r = c.replan_options(Path::new("run"), None).settings;
        assert_eq!((r.clearance_m, r.home), (1.5, Some([0.0, 1.0, 2.0])));
        let d = c.detect_options(Path::new("run"), Path::new("m.onnx"), None, None, None);
        assert_eq!(d.detect.settings.confidence, 0.4);
        assert!(toml::from_str::<RunConfig>("[detect]\nconfidense = 0.4\n").is_err());
        let off = RunConfig::parse("[detect]\nmerge_gap = \"off\"\n").unwrap();
        let d = off.detect_options(Path::new("run"), Path::new("m.onnx"), None, None, None);
        assert_eq!(d.detect.settings.merge_gap.pixels(), None);
        assert!(RunConfig::parse("[detect]\nmerge_gap = \"of\"\n").is_err());
        assert!(toml::from_str::<RunConfig>("[detector]\n").is_err());
    }

    /// Read `text` as postflight.toml and build every stage's options.
    fn use_config(text: &[u8]) {
        let Ok(c) = RunConfig::parse(&String::from_utf8_lossy(text)) else {
            return;
        };
        let (run, file) = (Path::new("run"), Path::new("f"));
        let _ = c.ingest_options(&[file.to_owned()], run);
        let _ = c.detect_options(run, file, None, None, None);
        let _ = c.localise_options(run, None, None, coverage::Targets::Plan);
        let _ = c.coverage_options(run, None, None, coverage::Targets::Plan);
        let _ = c.replan_options(run, None);
    }

    #[test]
    fn a_config_cut_anywhere_flipped_or_absurd_reads_or_fails_in_one_line() {
        let full = RunConfig::parse(super::FULL).unwrap();
        assert_eq!(full.keys_set(), full.keys(), "the example sets every key");
        let bytes = super::FULL.as_bytes();
        for cut in 0..bytes.len() {
            use_config(&bytes[..cut]);
        }
        let mut rng = sim::rng::Rng::new(3);
        for _ in 0..3000 {
            let mut damaged = bytes.to_vec();
            let at = rng.next_u64() as usize % damaged.len();
            damaged[at] ^= 1 << (rng.next_u64() % 8);
            use_config(&damaged);
        }
        // Absurd values, deep nesting and a huge file fail with a line and column.
        let deep = format!(
            "[replan]\nhome = {}{}\n",
            "[".repeat(100_000),
            "]".repeat(100_000)
        );
        let huge = format!("[replan]\nseed = 1{}\n", "0".repeat(1_000_000));
        let cases = [
            "[replan]\nseed = -1\n".to_string(),
            "[replan]\ngeo_origin = [91.0, 0.0, 0.0]\n".to_string(),
            "[replan]\nhome = [1e999, 0, 0]\n".to_string(),
            "[detect]\nimage_size = 99999999999999999999\n".to_string(),
            "[view]\nviews_required = \"many\"\n".to_string(),
            deep,
            huge,
        ];
        for text in &cases {
            use_config(text.as_bytes());
            if let Err(why) = RunConfig::parse(text) {
                assert!(!why.contains('\n') && why.contains("line"), "{why}");
            }
        }
        let err = RunConfig::parse("[view]\nmax_distance_m = 5.0\ncone_apex = 20\n").unwrap_err();
        assert!(err.contains("line 3, column 1"), "{err}");
        // A geo origin off the Earth is refused as the file is read, by key.
        let err = RunConfig::parse("[replan]\ngeo_origin = [91.0, 0.0, 0.0]\n").unwrap_err();
        assert!(
            err.contains("line 2") && err.contains("geo_origin must be"),
            "{err}"
        );
    }

    #[test]
    fn other_stages_tables_are_left_alone_and_unknown_tables_refused() {
        let c: RunConfig = toml::from_str(
            "[detect]\nconfidence = 0.3\n[view]\nmax_distance_m = 4.0\n[replan]\nseed = 2\n",
        )
        .unwrap();
        assert_eq!(c.view.max_distance_m, Some(4.0));
        assert!(toml::from_str::<RunConfig>("[veiw]\nmax_distance_m = 4.0\n").is_err());
    }

    #[test]
    fn each_table_is_named_as_its_settings_declare_it() {
        let names: BTreeSet<String> = RunConfig::default()
            .keys()
            .into_iter()
            .map(|(t, _)| t)
            .collect();
        let declared: BTreeSet<String> = tables().iter().map(|t| t.name.to_string()).collect();
        assert_eq!(names, declared);
        // Every key is a flag of the same id, and every flag a key.
        for table in tables() {
            let keys: BTreeSet<String> = RunConfig::default()
                .keys()
                .into_iter()
                .filter(|(t, _)| t == table.name)
                .map(|(_, k)| k)
                .collect();
            let flags: BTreeSet<String> = table
                .args
                .get_arguments()
                .inspect(|a| assert!(a.get_long().is_some(), "{:?} has no flag", a.get_id()))
                .map(|a| a.get_id().to_string())
                .collect();
            assert_eq!(keys, flags, "[{}]", table.name);
        }
    }

    #[test]
    fn flags_go_over_the_file_and_the_file_over_the_defaults() {
        let file =
            RunConfig::parse("[view]\nmax_distance_m = 4.0\nmin_distance_m = 1.0\n").unwrap();
        let flags = RunConfig {
            view: ViewSettings {
                max_distance_m: Some(3.0),
                ..ViewSettings::default()
            },
            ..RunConfig::default()
        };
        let view = flags.over(&file).view.resolve();
        assert_eq!((view.max_distance_m, view.min_distance_m), (3.0, 1.0));
        assert_eq!(
            view.cone_apex_deg,
            postflight_core::ViewModel::default().cone_apex_deg
        );
    }

    /// `docs/cli.md`'s list of `postflight.toml` keys, table by table.
    fn documented_keys() -> BTreeSet<(String, String)> {
        let docs = include_str!("../docs/cli.md");
        docs.lines()
            .filter_map(|line| {
                let (table, keys) = line.strip_prefix('[')?.split_once("]")?;
                let keys = keys.trim_start().strip_prefix('#')?;
                Some((table.to_string(), keys.to_string()))
            })
            .flat_map(|(table, keys)| {
                // Values in parentheses are examples, not keys.
                let mut depth = 0;
                let keys: String = keys
                    .chars()
                    .filter(|c| {
                        depth += i32::from(*c == '(') - i32::from(*c == ')');
                        depth == 0 && *c != ')'
                    })
                    .collect();
                keys.split(',')
                    .map(|k| (table.clone(), k.trim().to_string()))
                    .collect::<Vec<_>>()
            })
            .collect()
    }

    #[test]
    fn the_reference_documents_every_key_and_flag_and_no_other() {
        let keys = RunConfig::default().keys();
        assert_eq!(
            documented_keys(),
            keys,
            "docs/cli.md's postflight.toml keys"
        );
        let docs = include_str!("../docs/cli.md");
        for table in tables() {
            for arg in table.args.get_arguments() {
                let flag = format!("--{}", arg.get_long().unwrap());
                assert!(docs.contains(&flag), "docs/cli.md does not mention {flag}");
            }
        }
        // Every flag the reference mentions is one some command has.
        let mut flags = BTreeSet::new();
        let mut cli = <crate::Cli as clap::CommandFactory>::command();
        cli.build();
        let mut commands = vec![cli];
        while let Some(command) = commands.pop() {
            flags.extend(
                command
                    .get_arguments()
                    .filter_map(|a| a.get_long())
                    .map(|l| format!("--{l}")),
            );
            commands.extend(command.get_subcommands().cloned());
        }
        for word in docs.split(|c: char| !(c.is_ascii_alphanumeric() || c == '-')) {
            // `--target-*` names the three target flags at once; the others
            // are sbatch's and scripts/setup's.
            let slurms = ["--array", "--cpus-per-task", "--slurm"];
            if word.starts_with("--")
                && word.len() > 2
                && !word.ends_with('-')
                && !slurms.contains(&word)
            {
                assert!(
                    flags.contains(word),
                    "docs/cli.md mentions {word}, which no command has"
                );
            }
        }
    }

    #[test]
    fn the_readme_example_reads() {
        let readme = include_str!("../README.md");
        let settings = &readme[readme.find("## Settings").unwrap()..];
        let start = settings.find("```toml\n").unwrap() + "```toml\n".len();
        let end = start + settings[start..].find("```").unwrap();
        let example = RunConfig::parse(&settings[start..end]).unwrap();
        assert!(!example.keys_set().is_empty());
    }
}
