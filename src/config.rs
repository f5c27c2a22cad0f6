//! `postflight.toml`: settings for every stage of `postflight run`, one
//! table per stage (`[ingest]`, `[detect]`, `[localise]`, `[view]`,
//! `[coverage]`, `[replan]`), every key optional; unknown tables and keys
//! are refused. `postflight coverage --config` reads the same file and uses
//! its `[view]` and `[coverage]` tables.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use postflight_core::PlanFile;
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RunConfig {
    pub ingest: IngestConfig,
    pub detect: DetectConfig,
    pub localise: LocaliseConfig,
    pub view: coverage::ViewSettings,
    pub coverage: coverage::CoverageSettings,
    pub replan: ReplanConfig,
}

/// How far apart detection boxes may be and still merge, as `--merge-gap`
/// and `merge_gap` take it: pixels, or `off`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum MergeGap {
    Pixels(f32),
    Off(Off),
}

/// The word `off` (a unit variant serialises as its name).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Off {
    Off,
}

impl MergeGap {
    pub fn pixels(self) -> Option<f32> {
        match self {
            MergeGap::Pixels(gap) => Some(gap),
            MergeGap::Off(_) => None,
        }
    }
}

impl std::fmt::Display for MergeGap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            MergeGap::Pixels(gap) => write!(f, "{gap}"),
            MergeGap::Off(_) => f.write_str("off"),
        }
    }
}

impl std::str::FromStr for MergeGap {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        if s.eq_ignore_ascii_case("off") {
            return Ok(MergeGap::Off(Off::Off));
        }
        s.parse()
            .map(MergeGap::Pixels)
            .map_err(|_| format!("'{s}' is neither a number of pixels nor 'off'"))
    }
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct IngestConfig {
    pub image_topics: Vec<String>,
    pub pose_topic: Option<String>,
    pub camera_info_topic: Option<String>,
    /// ROS camera-calibration YAML, for recordings without CameraInfo.
    pub camera_info_file: Option<PathBuf>,
    pub map_topic: Option<String>,
    pub body_frame: Option<String>,
    pub world_frame: Option<String>,
    pub max_pose_gap_s: Option<f64>,
    /// Fail on a truncated recording instead of salvaging it.
    pub strict: Option<bool>,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DetectConfig {
    pub prompts: Vec<String>,
    pub embeddings: Option<PathBuf>,
    pub confidence: Option<f32>,
    pub iou: Option<f32>,
    pub merge_gap: Option<MergeGap>,
    pub image_size: Option<u32>,
    pub tile: Option<u32>,
    pub tile_overlap: Option<f32>,
    pub batch: Option<usize>,
    pub device: Option<DeviceName>,
}

/// Where inference runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum DeviceName {
    Cpu,
    Cuda,
    Tensorrt,
}

impl DeviceName {
    pub fn device(self) -> detect::Device {
        match self {
            Self::Cpu => detect::Device::Cpu,
            Self::Cuda => detect::Device::Cuda,
            Self::Tensorrt => detect::Device::TensorRt,
        }
    }
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LocaliseConfig {
    pub max_range_m: Option<f64>,
    pub link_distance_m: Option<f64>,
    pub max_normal_angle_deg: Option<f64>,
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ReplanConfig {
    pub home: Option<[f64; 3]>,
    pub clearance_m: Option<f64>,
    pub max_sortie_length_m: Option<f64>,
    pub battery_minutes: Option<f64>,
    pub gaps: Option<replan::GapChoice>,
    pub speed_m_s: Option<f64>,
    pub hover_s: Option<f64>,
    pub solver_time_limit_s: Option<f64>,
    pub seed: Option<u64>,
    /// `[LAT, LON, ALT]` or `[LAT, LON, ALT, YAW_DEG]`.
    pub geo_origin: Option<Vec<f64>>,
}

impl RunConfig {
    /// Every `(table, key)` of the file, set or not.
    #[cfg(test)]
    pub fn keys(&self) -> BTreeSet<(String, String)> {
        self.keys_where(|_| true)
    }

    /// The `(table, key)`s this file sets.
    pub fn keys_set(&self) -> BTreeSet<(String, String)> {
        self.keys_where(|v| !v.is_null() && v.as_array().is_none_or(|a| !a.is_empty()))
    }

    fn keys_where(&self, keep: impl Fn(&serde_json::Value) -> bool) -> BTreeSet<(String, String)> {
        let value = serde_json::to_value(self).expect("the config serialises to JSON");
        let tables = value.as_object().into_iter().flatten();
        tables
            .flat_map(|(table, keys)| {
                keys.as_object()
                    .into_iter()
                    .flatten()
                    .filter(|(_, v)| keep(v))
                    .map(move |(key, _)| (table.clone(), key.clone()))
            })
            .collect()
    }

    /// The file at `path`, or every setting unset without one.
    pub fn load_or_default(path: Option<&Path>) -> anyhow::Result<Self> {
        path.map_or_else(|| Ok(Self::default()), Self::load)
    }

    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| anyhow::anyhow!("cannot read config {}: {e}", path.display()))?;
        Self::parse(&text).map_err(|why| anyhow::anyhow!("config {}: {why}", path.display()))
    }

    /// A `postflight.toml`'s text, or a one-line error naming the line and
    /// column.
    pub fn parse(text: &str) -> Result<Self, String> {
        toml::from_str(text).map_err(|e| {
            format!(
                "{}; tables are [ingest], [detect], [localise], [view], [coverage] and [replan] (see docs/cli.md)",
                e.to_string().trim().replace('\n', " ")
            )
        })
    }

    pub fn ingest_options(&self, flight: &Path, out: &Path) -> ingest::IngestOptions {
        let c = &self.ingest;
        let defaults = ingest::IngestOptions::new(flight.to_owned(), out.to_owned());
        ingest::IngestOptions {
            image_topics: c.image_topics.clone(),
            pose_topic: c.pose_topic.clone(),
            camera_info_topic: c.camera_info_topic.clone(),
            camera_info_file: c.camera_info_file.clone(),
            map_topic: c.map_topic.clone(),
            body_frame: c.body_frame.clone(),
            world_frame: c.world_frame.clone(),
            max_pose_gap_s: c.max_pose_gap_s.unwrap_or(defaults.max_pose_gap_s),
            strict: c.strict.unwrap_or(defaults.strict),
            ..defaults
        }
    }

    pub fn detect_options(
        &self,
        run: &Path,
        model: &Path,
        onnxruntime: Option<&Path>,
    ) -> detect::DetectOptions {
        let c = &self.detect;
        let d = detect::DetectOptions::new(run.to_owned(), model.to_owned());
        detect::DetectOptions {
            prompts: if c.prompts.is_empty() {
                d.prompts.clone()
            } else {
                c.prompts.clone()
            },
            embeddings: c.embeddings.clone(),
            confidence: c.confidence.unwrap_or(d.confidence),
            iou: c.iou.unwrap_or(d.iou),
            merge_gap: c.merge_gap.map_or(d.merge_gap, MergeGap::pixels),
            image_size: c.image_size.unwrap_or(d.image_size),
            tile: c.tile.or(d.tile),
            tile_overlap: c.tile_overlap.unwrap_or(d.tile_overlap),
            batch: c.batch.unwrap_or(d.batch),
            device: c.device.map_or(d.device, DeviceName::device),
            onnxruntime: onnxruntime.map(Path::to_path_buf),
            ..d
        }
    }

    pub fn localise_options(
        &self,
        run: &Path,
        map: Option<&Path>,
        plan: Option<&PlanFile>,
    ) -> localise::LocaliseOptions {
        let c = &self.localise;
        let d = localise::LocaliseOptions::new(run.to_owned());
        localise::LocaliseOptions {
            map: map.map(Path::to_path_buf),
            plan: plan.cloned(),
            max_range_m: c.max_range_m.unwrap_or(d.max_range_m),
            fusion: localise::FusionOptions {
                link_distance: c.link_distance_m.unwrap_or(d.fusion.link_distance),
                max_normal_angle_deg: c
                    .max_normal_angle_deg
                    .unwrap_or(d.fusion.max_normal_angle_deg),
            },
            view: self.view,
            ..d
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
            settings: self.coverage,
            ..coverage::CoverageOptions::new(run.to_owned())
        }
    }

    pub fn replan_options(
        &self,
        run: &Path,
        map: Option<&Path>,
    ) -> anyhow::Result<replan::ReplanOptions> {
        let c = &self.replan;
        let d = replan::ReplanOptions::new(run.to_owned());
        let mut options = replan::ReplanOptions {
            map: map.map(Path::to_path_buf),
            home: c.home.or(d.home),
            clearance_m: c.clearance_m.unwrap_or(d.clearance_m),
            max_sortie_length_m: c.max_sortie_length_m.or(d.max_sortie_length_m),
            battery_minutes: c.battery_minutes.unwrap_or(d.battery_minutes),
            gaps: c.gaps.unwrap_or(d.gaps),
            speed_m_s: c.speed_m_s.unwrap_or(d.speed_m_s),
            hover_s: c.hover_s.unwrap_or(d.hover_s),
            ..d
        };
        if let Some(s) = c.solver_time_limit_s {
            options.solver.time_limit = Some(replan::stage::solver_time_limit(s)?);
        }
        if let Some(seed) = c.seed {
            options.solver.seed = seed;
        }
        if let Some(values) = &c.geo_origin {
            let origin = postflight_core::geo::GeoOrigin::from_values(values).map_err(|why| {
                postflight_core::InvalidSetting::new(
                    replan::stage::keys::GEO_ORIGIN,
                    format!("{values:?}"),
                    format!("[LAT, LON, ALT] or [LAT, LON, ALT, YAW_DEG] ({why})"),
                )
            })?;
            options.geo_origin = Some(origin);
        }
        Ok(options)
    }
}

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
        assert_eq!(c.detect.device, Some(DeviceName::Cuda));
        assert_eq!(c.view.max_distance_m, Some(6.0));
        let r = c.replan_options(Path::new("run"), None).unwrap();
        assert_eq!((r.clearance_m, r.home), (1.5, Some([0.0, 1.0, 2.0])));
        let d = c.detect_options(Path::new("run"), Path::new("m.onnx"), None);
        assert_eq!(d.confidence, 0.4);
        assert!(toml::from_str::<RunConfig>("[detect]\nconfidense = 0.4\n").is_err());
        let off = RunConfig::parse("[detect]\nmerge_gap = \"off\"\n").unwrap();
        let d = off.detect_options(Path::new("run"), Path::new("m.onnx"), None);
        assert_eq!(d.merge_gap, None);
        assert!(RunConfig::parse("[detect]\nmerge_gap = \"of\"\n").is_err());
        assert!(toml::from_str::<RunConfig>("[detector]\n").is_err());
    }

    /// Every table and key set.
    const FULL: &str = r#"
[ingest]
image_topics = ["/camera/image_raw"]
pose_topic = "/lio_sam/mapping/odometry"
camera_info_topic = "/camera/camera_info"
camera_info_file = "camera.yaml"
map_topic = "/lio_sam/mapping/map_global"
body_frame = "base_link"
world_frame = "map"
max_pose_gap_s = 0.5
strict = false
[detect]
prompts = ["crack"]
embeddings = "embeddings.json"
confidence = 0.25
iou = 0.5
merge_gap = 8.0
image_size = 640
tile = 640
tile_overlap = 0.2
batch = 4
device = "cpu"
[localise]
max_range_m = 30.0
link_distance_m = 0.3
max_normal_angle_deg = 30.0
[view]
cone_apex_deg = 20.0
min_distance_m = 2.0
max_distance_m = 5.0
max_incidence_deg = 60.0
max_blur_px = 3.0
max_gsd_mm = 6.0
views_required = 1
[coverage]
views_near_defects = 2
defect_radius_m = 1.0
exposure_s = 0.002
[replan]
home = [0.0, 0.0, 0.0]
clearance_m = 1.0
max_sortie_length_m = 800.0
battery_minutes = 20.0
gaps = "all"
speed_m_s = 2.0
hover_s = 2.0
solver_time_limit_s = 10.0
seed = 7
geo_origin = [47.397742, 8.545594, 488.0, 23.5]
"#;

    /// Read `text` as postflight.toml and build every stage's options.
    fn use_config(text: &[u8]) {
        let Ok(c) = RunConfig::parse(&String::from_utf8_lossy(text)) else {
            return;
        };
        let (run, file) = (Path::new("run"), Path::new("f"));
        let _ = c.ingest_options(file, run);
        let _ = c.detect_options(run, file, None);
        let _ = c.localise_options(run, None, None);
        let _ = c.coverage_options(run, None, None, coverage::Targets::Plan);
        let _ = c.replan_options(run, None);
    }

    #[test]
    fn a_config_cut_anywhere_flipped_or_absurd_reads_or_fails_in_one_line() {
        let full = RunConfig::parse(FULL).unwrap();
        assert_eq!(full.keys_set(), full.keys(), "the example sets every key");
        let bytes = FULL.as_bytes();
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
        let geo = RunConfig::parse("[replan]\ngeo_origin = [91.0, 0.0, 0.0]\n").unwrap();
        let err = geo
            .replan_options(Path::new("run"), None)
            .unwrap_err()
            .to_string();
        assert!(err.contains("[replan] geo_origin"), "{err}");
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
}
