//! Synthetic inspection flights with ground truth.
//!
//! This crate owns the simulator behind `postflight simulate` and
//! `postflight demo`: a scene (a girder bridge, a tower, or any OBJ mesh)
//! with seeded cracks drawn on its surfaces, an inspection plan for it, and a
//! flight that flies the plan imperfectly (a skipped part, rushed and blurred
//! legs, pose noise, dropped frames). It writes what a real flight leaves
//! behind: a ROS 2 MCAP recording (rendered JPEG frames, CameraInfo, poses,
//! `/tf_static`, the SLAM map), `map.ply` and `plan.json`, plus `truth.json`
//! with where every crack really is and what every frame really saw. Nothing
//! downstream can tell the recording was simulated; it depends only on
//! `ingest`'s message and plan types.

pub mod coverage;
pub mod crack;
pub mod distractor;
mod error;
pub mod flight;
pub mod gps;
pub mod planner;
pub mod record;
pub mod render;
pub mod repeat;
pub mod rng;
pub mod scene;
pub mod section;
pub mod sortie;
pub mod spall;
pub mod truth;

use std::ffi::OsString;
use std::io::Cursor;
use std::path::{Path, PathBuf};

use ingest::ros::msg;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use postflight_core::{Distortion, Intrinsics};

use crate::crack::Cracks;
use crate::distractor::Distractors;
use crate::flight::Flight;
use crate::record::{Recorder, header, ros_pose};
use crate::render::RayTable;
use crate::rng::Rng;
use crate::scene::{Class, Scene, area};
use crate::sortie::Sorties;
use crate::spall::Spalls;
use crate::truth::{CrackTruth, FrameTruth, Truth};
pub use error::SimError;
use postflight_core::serde_pose::PoseJson;

/// A built-in structure to fly around.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum BuiltIn {
    /// A steel-girder bridge: a deck on three girders on two piers, with a
    /// tree and a lamp pole nearby.
    GirderBridge,
    /// A concrete silo tower with a pole beside it.
    Tower,
}

/// What to simulate: each option is its `postflight simulate` flag (its
/// doc the flag's help, its default the flag's), and [`SimOptions::new`]
/// is the flight the flags give by default.
#[derive(Debug, Clone, clap::Args)]
pub struct SimOptions {
    /// Directory to write the flight into (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// Built-in structure to fly around.
    #[arg(long, value_enum, default_value_t = BuiltIn::GirderBridge)]
    pub scene: BuiltIn,
    /// Fly around this triangle mesh instead (Wavefront OBJ, z up, metres).
    #[arg(long, value_name = "STRUCTURE.obj", conflicts_with = "scene")]
    pub mesh: Option<PathBuf>,
    /// Seed: the same seed gives byte-identical files.
    #[arg(long, default_value_t = Self::DEFAULT_SEED)]
    pub seed: u64,
    /// Number of camera frames (a few are dropped, as recorders do).
    #[arg(long, default_value_t = Self::DEFAULT_FRAMES)]
    pub frames: u32,
    /// Frame width, pixels.
    #[arg(long, default_value_t = Self::DEFAULT_WIDTH)]
    pub width: u32,
    /// Frame height, pixels.
    #[arg(long, default_value_t = Self::DEFAULT_HEIGHT)]
    pub height: u32,
    /// Number of cracks drawn on the structure.
    #[arg(long, default_value_t = Self::DEFAULT_CRACKS)]
    pub cracks: usize,
    /// Also draw this many patterns of cracks: three to five cracks side
    /// by side on one face, heavy (0.10 to 0.25 m apart) or moderate (0.35
    /// to 0.8 m), map or transverse cracking that the manual judges by its
    /// spacing; truth.json numbers each crack's pattern.
    #[arg(
        long = "crack-patterns",
        default_value_t = 0,
        value_name = "N",
        conflicts_with = "repeat_of"
    )]
    pub crack_patterns: usize,
    /// Also draw this many spalls: concrete broken out of the structure's
    /// faces, 8 to 45 cm across and 8 to 45 mm deep, each a depression in
    /// the geometry and the map with a rough, darker floor; two in five of
    /// those deeper than 20 mm show reinforcing bars. truth.json lists
    /// them (and their bars, as exposed reinforcement) in `area_defects`.
    #[arg(
        long,
        default_value_t = 0,
        value_name = "N",
        conflicts_with = "repeat_of"
    )]
    pub spalls: usize,
    /// The widths a pattern's cracks open and close between (widest
    /// mid-way, as --crack-widths): fine, so that their spacing decides
    /// their state.
    #[arg(long, value_name = "MIN_MM,MAX_MM", value_parser = crack::WidthRange::parse, default_value = "0.4,1.0")]
    pub pattern_widths: crack::WidthRange,
    /// Record an ideal lens instead of plumb_bob distortion (and render
    /// without it).
    #[arg(long = "no-distortion", action = clap::ArgAction::SetFalse)]
    pub distortion: bool,
    /// Fly a photogrammetry survey instead of one viewpoint per square
    /// metre: a photo at each viewpoint, neighbours overlapping by FORWARD
    /// along each face and SIDE across it (0.8,0.7 as survey flights fly);
    /// --frames must be at least the viewpoints it plans (it says how many).
    #[arg(long, value_name = "FORWARD,SIDE", value_parser = planner::Overlap::parse, conflicts_with = "repeat_of")]
    pub overlap: Option<planner::Overlap>,
    /// The lens's focal length, pixels (default: 1.5 times --width, a 37
    /// degree view across).
    #[arg(long = "focal", value_name = "PIXELS")]
    pub focal_px: Option<f64>,
    /// How far in front of the structure the plan flies, metres.
    #[arg(long = "standoff", default_value_t = planner::STANDOFF, value_name = "METRES")]
    pub standoff_m: f64,
    /// Cracks open and close along their length between these widths
    /// (widest mid-way, hairline at the tips), drawn by the share of each
    /// pixel they cover, so width can be measured; truth.json gives the
    /// width along each crack and its condition state. Without it every
    /// crack has one width, 1 to 5 mm.
    #[arg(long, value_name = "MIN_MM,MAX_MM", value_parser = crack::WidthRange::parse, conflicts_with = "repeat_of")]
    pub crack_widths: Option<crack::WidthRange>,
    /// Draw what a real surface shows besides cracks: formwork joints,
    /// stains, rust streaks and shadow edges (listed in truth.json).
    #[arg(long)]
    pub distractors: bool,
    /// Give the concrete the texture real concrete shows at centimetre
    /// scale (aggregate, formwork board grain, weathering streaks), which
    /// structure-from-motion matches from frame to frame; without it the
    /// surfaces are as the default flights have always been.
    #[arg(
        long = "textured",
        action = clap::ArgAction::SetTrue,
        value_parser = clap::builder::TypedValueParser::map(clap::builder::BoolishValueParser::new(), render::Surface::textured_if),
    )]
    pub surface: render::Surface,
    /// The lens's point-spread function, a Gaussian's standard deviation in
    /// pixels (0: a perfect lens): a line thinner than a pixel is spread
    /// over two or three, as a real camera spreads it. With the pixel's
    /// own area, postflight measures a thin crack's profile 2 px wide at
    /// half depth, as the crack-width gauge readings' photos show
    /// (docs/evaluation.md).
    #[arg(long = "lens-blur", value_name = "PIXELS", default_value_t = Self::DEFAULT_LENS_BLUR_PX)]
    pub lens_blur_px: f64,
    /// Carry the camera on a gimbal (its pitch on /tf) and also plan a
    /// viewpoint looking straight down over each patch of faces pointing
    /// up, such as a deck's top (a fixed camera sees those only grazing).
    #[arg(long)]
    pub gimbal: bool,
    /// Compression of the camera frames.
    #[arg(long, value_enum, default_value_t = ImageFormat::Jpeg)]
    pub image_format: ImageFormat,
    /// Noise of the recorded SLAM poses.
    #[command(flatten)]
    pub pose_noise: truth::PoseNoise,
    /// Fly an earlier flight's structure and cracks again, changed.
    #[command(flatten)]
    pub repeat: Option<repeat::Repeat>,
    /// Record the flight as sorties, one recording per battery, or flown by
    /// a team.
    #[command(flatten)]
    pub sorties: sortie::SortieOptions,
    /// Record GPS fixes (sensor_msgs/NavSatFix, 5 Hz, 0.3 m noise across
    /// and 0.5 m up) on /gps/fix, the world frame's origin here.
    #[arg(long, value_name = "LAT,LON,ALT[,YAW_DEG]", allow_hyphen_values = true)]
    pub gps: Option<postflight_core::geo::GeoOrigin>,
}

/// Compression of recorded camera frames (`sensor_msgs/CompressedImage` format).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ImageFormat {
    /// JPEG quality 92, as camera drivers record.
    Jpeg,
    /// Lossless PNG, so a frame decodes to the same pixels in every decoder.
    Png,
}

impl SimOptions {
    pub const DEFAULT_SEED: u64 = 1;
    pub const DEFAULT_FRAMES: u32 = 300;
    pub const DEFAULT_WIDTH: u32 = 640;
    pub const DEFAULT_HEIGHT: u32 = 480;
    pub const DEFAULT_CRACKS: usize = 40;
    pub const DEFAULT_LENS_BLUR_PX: f64 = 0.6;

    /// The default flight, written into `out`: every option its flag's
    /// default.
    pub fn new(out: PathBuf) -> Self {
        let command = <Self as clap::Args>::augment_args(clap::Command::new("simulate"));
        let args = [
            OsString::from("simulate"),
            "--out".into(),
            out.into_os_string(),
        ];
        // The declared defaults are options: a unit test parses them.
        let matches = command
            .try_get_matches_from(args)
            .expect("the defaults parse");
        <Self as clap::FromArgMatches>::from_arg_matches(&matches)
            .expect("the defaults are options")
    }
}

/// What a simulation wrote.
#[derive(Debug, Clone, serde::Serialize)]
pub struct SimSummary {
    pub frames: u32,
    pub dropped_frames: u32,
    pub cracks: usize,
    pub spalls: usize,
    pub duration_s: f64,
    pub map_points: usize,
    /// Every recording, in flying order (`flight.mcap` alone when whole).
    pub recordings: Vec<PathBuf>,
}

/// Camera mounting: ahead of and below the body origin, pitched down.
pub const CAMERA_OFFSET: [f64; 3] = [0.25, 0.0, -0.12];
pub const CAMERA_PITCH_DEG: f64 = 12.0;
/// Exposure time of every frame, seconds.
pub const EXPOSURE_S: f64 = 0.008;
/// Share of frames the recorder dropped.
const DROP_RATE: f64 = 0.02;
/// Start of the simulated clock (2025-06-15T12:00:00Z), ns.
const T0_NS: i64 = 1_749_988_800_000_000_000;

/// `T_body_camera` (optical frame: x right, y down, z forward), as
/// `T_body_camera_link` and `T_camera_link_optical`.
pub fn body_to_camera() -> (Isometry3<f64>, Isometry3<f64>) {
    body_to_camera_pitched(CAMERA_PITCH_DEG.to_radians())
}

/// [`body_to_camera`] with the camera pitched `pitch` radians down.
fn body_to_camera_pitched(pitch: f64) -> (Isometry3<f64>, Isometry3<f64>) {
    let link = Isometry3::from_parts(
        Translation3::from(Vector3::from(CAMERA_OFFSET)),
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), pitch),
    );
    let optical = Isometry3::from_parts(
        Translation3::identity(),
        UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(0.5, -0.5, 0.5, -0.5)),
    );
    (link, optical)
}

fn intrinsics(width: u32, height: u32, focal_px: Option<f64>, distortion: bool) -> Intrinsics {
    // A narrow lens (37 degrees across), as inspection cameras use for mm detail.
    let focal = focal_px.unwrap_or(f64::from(width) * 1.5);
    let pinhole = Intrinsics::pinhole(width, height, focal);
    if !distortion {
        return pinhole;
    }
    Intrinsics {
        distortion: Distortion::PlumbBob([-0.08, 0.025, 0.0004, -0.0003, 0.0]),
        ..pinhole
    }
}

fn ns(t: f64) -> i64 {
    T0_NS + (t * 1e9).round() as i64
}

/// Simulate a flight into `options.out`; `progress(done, total)` per frame.
pub fn simulate(
    options: &SimOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<SimSummary, SimError> {
    check(options)?;
    let world = World::new(options)?;
    std::fs::create_dir_all(&options.out).map_err(SimError::write(&options.out))?;
    let duration = world.flight.duration();
    let frame_times = world.flight.frame_times(options.frames as usize);
    let mut sorties = Sorties::create(
        &options.out,
        &options.sorties,
        &frame_times,
        duration,
        (options.gimbal, options.gps.is_some()),
    )?;
    for (rec, sortie) in sorties.each() {
        write_mounting(rec, &world, sortie.stamp(sortie.start_s()))?;
    }
    let recorded = record_frames(&mut sorties, &world, &frame_times, options, progress)?;
    let map = map_points(
        &world.scene,
        &world.spalls,
        &mut Rng::stream(options.seed, "map"),
    );
    write_maps(&mut sorties, &map)?;
    let sortie_truth = sorties.truth(ns);
    let recordings = sorties.finish(&options.out)?;
    record::write_ply(&options.out.join("map.ply"), &map)?;
    let truth = Truth {
        scene: world.scene.name.clone(),
        seed: options.seed,
        exposure_s: EXPOSURE_S,
        camera: world.k.clone(),
        t_body_camera: PoseJson::from(&world.body_camera()),
        gimbal: options.gimbal,
        pose_noise: options.pose_noise,
        skipped_viewpoints: world.flight.skipped.clone(),
        crack_widths: world.crack_widths,
        distractors: world
            .marks
            .0
            .iter()
            .map(|m| truth::DistractorTruth::new(m, &world.scene))
            .collect(),
        area_defects: world.spalls.truths(&world.scene),
        cracks: world
            .cracks
            .0
            .iter()
            .map(|c| CrackTruth::new(c, &world.scene, &world.plan.grid()))
            .collect(),
        coverage: true_coverage(&world, &recorded.views),
        frames: recorded.frames,
        repeat: options
            .repeat
            .as_ref()
            .zip(world.changes.clone())
            .map(|(r, changes)| repeat::truth(r, changes)),
        sorties: sortie_truth,
        gps: options.gps.map(gps::GpsTruth::new),
    };
    write_json(&options.out.join("plan.json"), &world.plan)?;
    write_json(&options.out.join("truth.json"), &truth)?;
    Ok(SimSummary {
        frames: options.frames - recorded.dropped,
        dropped_frames: recorded.dropped,
        cracks: world.cracks.0.len(),
        spalls: world.spalls.0.len(),
        duration_s: duration,
        map_points: map.len(),
        recordings,
    })
}

fn check(options: &SimOptions) -> Result<(), SimError> {
    if options.frames < 2 || options.width < 16 || options.height < 16 {
        return Err(SimError::FlightTooSmall);
    }
    if options.sorties.recordings() == 0 || options.sorties.recordings() > options.frames {
        return Err(SimError::Sorties {
            sorties: options.sorties.recordings(),
            frames: options.frames,
        });
    }
    let noise = options.pose_noise;
    if !(noise.position_m >= 0.0
        && noise.position_m < 10.0
        && noise.yaw_rad >= 0.0
        && noise.yaw_rad < 1.0)
    {
        return Err(SimError::PoseNoise);
    }
    if !(0.0..=MAX_LENS_BLUR_PX).contains(&options.lens_blur_px) {
        return Err(SimError::LensBlur {
            px: options.lens_blur_px,
        });
    }
    Ok(())
}

/// The widest lens blur simulated, pixels: a camera this far out of focus
/// records no crack.
pub const MAX_LENS_BLUR_PX: f64 = 10.0;

/// What the flight is made of: the structure with its cracks, the plan,
/// the flight flown and the camera.
struct World {
    scene: Scene,
    cracks: Cracks,
    /// Marks on the surface that are not cracks.
    marks: Distractors,
    spalls: Spalls,
    /// The widths cracks taper between (a repeat's: its earlier flight's).
    crack_widths: Option<crack::WidthRange>,
    /// A repeat flight's changes since the earlier one.
    changes: Option<Vec<repeat::CrackChange>>,
    plan: postflight_core::InspectionPlan,
    flight: Flight,
    k: Intrinsics,
    rays: RayTable,
    /// `T_body_camera_link` and `T_camera_link_optical` (the gimbal's at
    /// its side pitch).
    mounting: (Isometry3<f64>, Isometry3<f64>),
    /// The camera link turns with the plan's gimbal pitch.
    gimbal: bool,
}

/// A flight's scene and cracks, the changes since the earlier flight (a
/// repeat's), and the widths its cracks taper between.
type Cracked = (
    Scene,
    Cracks,
    Option<Vec<repeat::CrackChange>>,
    Option<crack::WidthRange>,
);

/// The flight's cracks on `scene`: drawn for a first flight (patterns,
/// then cracks, tapered where asked), or for a repeat the earlier
/// flight's changed, scene and cracks moved into this flight's SLAM frame.
fn cracked(scene: Scene, options: &SimOptions) -> Result<Cracked, SimError> {
    match &options.repeat {
        None => {
            // The patterns first: each needs more room on one face.
            let mut cracks = Cracks(Vec::new());
            cracks.add_patterns(
                &scene,
                options.crack_patterns,
                options.pattern_widths,
                &mut Rng::stream(options.seed, "crack patterns"),
            );
            cracks.add(
                &scene,
                options.cracks,
                &mut Rng::stream(options.seed, "cracks"),
            );
            if let Some(range) = options.crack_widths {
                cracks.taper(range, &mut Rng::stream(options.seed, "crack widths"));
            }
            Ok((scene, cracks, None, options.crack_widths))
        }
        Some(r) => {
            let earlier = repeat::Earlier::read(r, &scene.name)?;
            let (cracks, changes) = repeat::change(
                &scene,
                earlier.cracks(&scene),
                earlier.crack_widths(),
                r,
                options.seed,
            );
            // The world as this flight's SLAM frame records it.
            let iso = r.frame_offset.isometry();
            let cracks = Cracks(cracks.0.iter().map(|c| c.transformed(&iso)).collect());
            Ok((
                scene.transformed(&iso),
                cracks,
                Some(changes),
                earlier.crack_widths(),
            ))
        }
    }
}

impl World {
    fn new(options: &SimOptions) -> Result<Self, SimError> {
        let scene = match (&options.mesh, options.scene) {
            (Some(path), _) => Scene::from_obj(path).map_err(|reason| SimError::Mesh {
                path: path.clone(),
                reason,
            })?,
            (None, BuiltIn::GirderBridge) => Scene::girder_bridge(),
            (None, BuiltIn::Tower) => Scene::tower(),
        };
        let seed = options.seed;
        let pitch = CAMERA_PITCH_DEG.to_radians();
        let mount = if options.gimbal {
            planner::Mount::Gimbal { pitch }
        } else {
            planner::Mount::Fixed { pitch }
        };
        let resolution = postflight_core::map::DEFAULT_RESOLUTION;
        let k = intrinsics(
            options.width,
            options.height,
            options.focal_px,
            options.distortion,
        );
        let spacing = match options.overlap {
            None => planner::Spacing::PATCHES,
            Some(overlap) => planner::Spacing::survey(
                overlap,
                (
                    options.standoff_m * f64::from(options.width) / k.fx,
                    options.standoff_m * f64::from(options.height) / k.fy,
                ),
            ),
        };
        let plan = planner::plan(&scene, resolution, mount, options.standoff_m, spacing);
        if options.overlap.is_some() && (options.frames as usize) < plan.viewpoints.len() {
            return Err(SimError::SurveyFrames {
                viewpoints: plan.viewpoints.len(),
                frames: options.frames,
            });
        }
        let (scene, cracks, changes, crack_widths) = cracked(scene, options)?;
        // A repeat flies the earlier mission again, where this flight's
        // SLAM frame has it.
        let plan = match &options.repeat {
            Some(r) => planner::reflown(plan, &r.frame_offset.isometry(), &scene),
            None => plan,
        };
        let spalls = Spalls::generate(
            &scene,
            options.spalls,
            &cracks.0,
            &mut Rng::stream(seed, "spalls"),
        );
        let marks = if options.distractors {
            Distractors::generate(&scene, &mut Rng::stream(seed, "distractors"))
        } else {
            Distractors::default()
        };
        if plan.viewpoints.len() < 3 {
            return Err(SimError::StructureTooSmall);
        }
        let flight = Flight::fly(&plan, &scene, &mut Rng::stream(seed, "flight"));
        Ok(Self {
            rays: RayTable::new(&k),
            scene,
            cracks,
            marks,
            spalls,
            crack_widths,
            changes,
            plan,
            flight,
            k,
            mounting: body_to_camera(),
            gimbal: options.gimbal,
        })
    }

    /// `T_body_camera` of the optical frame (a gimbal's at its side pitch).
    fn body_camera(&self) -> Isometry3<f64> {
        self.mounting.0 * self.mounting.1
    }

    /// `T_body_camera` of the optical frame with the camera pitched
    /// `pitch` radians down (a fixed camera keeps its mounting).
    fn body_camera_pitched(&self, pitch: f64) -> Isometry3<f64> {
        if !self.gimbal {
            return self.body_camera();
        }
        let (link, optical) = body_to_camera_pitched(pitch);
        link * optical
    }

    /// `T_body_camera` of the optical frame at `t` seconds.
    fn body_camera_at(&self, t: f64) -> Isometry3<f64> {
        self.body_camera_pitched(self.flight.camera_pitch(t))
    }

    /// The true camera pose at `t` seconds.
    fn camera_at(&self, t: f64) -> Isometry3<f64> {
        self.flight.body_pose(t) * self.body_camera_at(t)
    }
}

/// `/tf_static` at `stamp`: the camera's mounting on the body (a gimbal's
/// camera link moves, so it goes on `/tf` with the poses).
fn write_mounting(rec: &mut Recorder, world: &World, stamp: i64) -> Result<(), SimError> {
    let (link, optical) = &world.mounting;
    let mut transforms = vec![transform(stamp, "camera_link", "camera_optical", optical)];
    if !world.gimbal {
        transforms.insert(0, transform(stamp, "base_link", "camera_link", link));
    }
    rec.write("/tf_static", stamp, &msg::TfMessage { transforms })
}

/// The map, at the end of each sortie that records one, in its SLAM frame.
fn write_maps(sorties: &mut Sorties, map: &[Point3<f64>]) -> Result<(), SimError> {
    for (rec, sortie) in sorties.each().filter(|(_, s)| s.with_map) {
        let points: Vec<Point3<f64>> = map.iter().map(|p| sortie.slam * p).collect();
        let end = sortie.stamp(sortie.end_s());
        rec.write(
            record::MAP_TOPIC,
            end + 500_000_000,
            &record::point_cloud(&points, end),
        )?;
    }
    Ok(())
}

/// A `/tf` transform: `child`'s pose in `parent` at `stamp`.
fn transform(stamp: i64, parent: &str, child: &str, p: &Isometry3<f64>) -> msg::TransformStamped {
    let pose = ros_pose(p);
    msg::TransformStamped {
        header: header(stamp, parent),
        child_frame_id: child.into(),
        transform: msg::Transform {
            translation: pose.position,
            rotation: pose.orientation,
        },
    }
}

/// What recording the frames left for the truth.
struct Recorded {
    frames: Vec<FrameTruth>,
    /// Every frame's camera, and whether it is usable.
    views: Vec<coverage::View>,
    dropped: u32,
}

/// The poses and the frames, in the order a recorder receives them: each
/// frame rendered (with its motion blur), compressed and written with its
/// CameraInfo and exposure, unless the recorder dropped it.
fn record_frames(
    sorties: &mut Sorties,
    world: &World,
    frame_times: &[f64],
    options: &SimOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Recorded, SimError> {
    let flight = &world.flight;
    let duration = flight.duration();
    let pose_times: Vec<f64> = (0..=(duration * flight::POSE_RATE).ceil() as usize)
        .map(|i| (i as f64 / flight::POSE_RATE).min(duration))
        .collect();
    let mut poses = PoseWriter {
        world,
        times: pose_times,
        next: 0,
        noise: Rng::stream(options.seed, "pose noise"),
        sigma: options.pose_noise,
    };
    let mut fixes = options.gps.map(|o| gps::GpsWriter::new(o, options.seed));
    let position = |t: f64| Point3::from(flight.body_pose(t).translation.vector);
    let mut drops = Rng::stream(options.seed, "dropped frames");
    let mut recorded = Recorded {
        frames: Vec::new(),
        views: Vec::new(),
        dropped: 0,
    };
    let n = options.frames;
    for (i, &t) in frame_times.iter().enumerate() {
        let i = i as u32;
        // Poses stamped up to this frame go first, as a recorder would receive them.
        poses.write_until(t, sorties)?;
        if let Some(f) = &mut fixes {
            f.write_until(t, duration, position, sorties)?;
        }
        let camera = world.camera_at(t);
        let is_dropped = i > 0 && i + 1 < n && drops.uniform() < DROP_RATE;
        let blur = blur_vector(world, t);
        let blur_px = blur.0.hypot(blur.1);
        let in_view = truth::cracks_in_view(
            &world.scene,
            &world.cracks.0,
            &world.k,
            &camera,
            blur_px,
            options.lens_blur_px,
        );
        if is_dropped {
            recorded.dropped += 1;
        } else {
            let img = render::motion_blur(
                render::render(
                    &world.scene,
                    &render::Drawn {
                        cracks: &world.cracks,
                        marks: &world.marks,
                        spalls: &world.spalls,
                    },
                    &world.rays,
                    &camera,
                    i,
                    options.surface,
                    options.lens_blur_px,
                ),
                blur.0,
                blur.1,
            );
            let (rec, _, stamp) = sorties.at(t);
            write_frame(rec, &img, options.image_format, &world.k, stamp)?;
        }
        recorded.views.push(coverage::View {
            camera,
            usable: !is_dropped && blur_px <= world.plan.view.max_blur_px,
        });
        recorded.frames.push(FrameTruth {
            index: i,
            time_ns: sorties.stamp(t),
            dropped: is_dropped,
            camera_pose: PoseJson::from(&camera),
            fast: flight.is_fast(t),
            blur_px,
            cracks: in_view,
            area_defects: world.spalls.seen_by(&world.scene, &world.k, &camera),
        });
        progress(u64::from(i) + 1, u64::from(n));
    }
    poses.write_until(duration, sorties)?;
    if let Some(f) = &mut fixes {
        f.write_until(duration, duration, position, sorties)?;
    }
    Ok(recorded)
}

/// One frame as a camera driver records it: the compressed image, its
/// CameraInfo and its exposure, logged 35 ms after the stamp.
fn write_frame(
    rec: &mut Recorder,
    img: &image::RgbImage,
    image_format: ImageFormat,
    k: &Intrinsics,
    stamp: i64,
) -> Result<(), SimError> {
    let mut data = Cursor::new(Vec::new());
    let format = match image_format {
        ImageFormat::Jpeg => {
            image::codecs::jpeg::JpegEncoder::new_with_quality(&mut data, 92).encode_image(img)?;
            "jpeg"
        }
        ImageFormat::Png => {
            img.write_to(&mut data, image::ImageFormat::Png)?;
            "png"
        }
    };
    let log = stamp + 35_000_000;
    rec.write(
        record::IMAGE_TOPIC,
        log,
        &msg::CompressedImage {
            header: header(stamp, "camera_optical"),
            format: format.into(),
            data: data.into_inner(),
        },
    )?;
    rec.write(record::CAMERA_INFO_TOPIC, log, &camera_info(k, stamp))?;
    rec.write(
        record::EXPOSURE_TOPIC,
        log,
        &msg::Float64 { data: EXPOSURE_S },
    )
}

/// The true coverage of the flight's views and of the plan's viewpoints.
fn true_coverage(world: &World, views: &[coverage::View]) -> coverage::CoverageTruth {
    let planned: Vec<(Isometry3<f64>, bool)> = world
        .plan
        .viewpoints
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let camera = Isometry3::from_parts(
                Translation3::from(Vector3::from(v.position)),
                UnitQuaternion::from_axis_angle(&Vector3::z_axis(), v.yaw),
            ) * world.body_camera_pitched(v.gimbal_pitch);
            (camera, world.flight.skipped.contains(&i))
        })
        .collect();
    coverage::coverage(
        &world.scene,
        &world.plan.grid(),
        &world.plan.target_voxels,
        &world.plan.view,
        &world.k,
        views,
        &planned,
    )
}

/// The recorded SLAM poses: noisy samples of the true body pose at
/// `POSE_RATE`, and a gimbal's camera link with each.
struct PoseWriter<'a> {
    world: &'a World,
    times: Vec<f64>,
    next: usize,
    noise: Rng,
    sigma: truth::PoseNoise,
}

impl PoseWriter<'_> {
    /// Write the poses stamped up to `t` not yet written.
    fn write_until(&mut self, t: f64, sorties: &mut Sorties) -> Result<(), SimError> {
        while let Some(&pt) = self.times.get(self.next).filter(|pt| **pt <= t) {
            let flight = &self.world.flight;
            let (rec, slam, stamp) = sorties.at(pt);
            let pose = slam * flight::noisy(&flight.body_pose(pt), &self.sigma, &mut self.noise);
            let msg = msg::PoseStamped {
                header: header(stamp, "map"),
                pose: ros_pose(&pose),
            };
            rec.write(record::POSE_TOPIC, stamp + 4_000_000, &msg)?;
            if self.world.gimbal {
                // The gimbal's encoders: its true pitch.
                let (link, _) = body_to_camera_pitched(flight.camera_pitch(pt));
                let link = transform(stamp, "base_link", "camera_link", &link);
                let msg = msg::TfMessage {
                    transforms: vec![link],
                };
                rec.write(record::TF_TOPIC, stamp + 4_000_000, &msg)?;
            }
            self.next += 1;
        }
        Ok(())
    }
}

fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<(), SimError> {
    let text = serde_json::to_string_pretty(value).map_err(|e| SimError::write(path)(e.into()))?;
    std::fs::write(path, text + "\n").map_err(SimError::write(path))
}

fn camera_info(k: &Intrinsics, stamp: i64) -> msg::CameraInfo {
    let d = match k.distortion {
        Distortion::PlumbBob(c) => c.to_vec(),
        _ => vec![0.0; 5],
    };
    msg::CameraInfo {
        header: header(stamp, "camera_optical"),
        height: k.height,
        width: k.width,
        distortion_model: "plumb_bob".into(),
        d,
        k: [k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0],
        r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        p: [
            k.fx, 0.0, k.cx, 0.0, 0.0, k.fy, k.cy, 0.0, 0.0, 0.0, 1.0, 0.0,
        ],
        binning_x: 0,
        binning_y: 0,
        roi: msg::RegionOfInterest {
            x_offset: 0,
            y_offset: 0,
            height: 0,
            width: 0,
            do_rectify: false,
        },
    }
}

/// Image motion during the exposure, pixels: where the scene point at the
/// image centre moves between the start and end of the exposure.
fn blur_vector(world: &World, t: f64) -> (f64, f64) {
    let camera = world.camera_at(t);
    let origin = Point3::from(camera.translation.vector);
    let axis = camera.rotation * Vector3::z();
    let target = world
        .scene
        .cast(&origin, &axis, 200.0)
        .map_or(origin + axis * 20.0, |h| h.point);
    let at = |time: f64| {
        let cam = world.camera_at(time.clamp(0.0, world.flight.duration()));
        world.k.project(&(cam.inverse() * target).coords)
    };
    match (at(t - EXPOSURE_S / 2.0), at(t + EXPOSURE_S / 2.0)) {
        (Some(a), Some(b)) => (b.x - a.x, b.y - a.y),
        _ => (0.0, 0.0),
    }
}

/// SLAM map points: samples of every surface near the structure (on a
/// spall's broken surface where one took the face away), with 1.5 cm
/// noise.
fn map_points(scene: &Scene, spalls: &Spalls, rng: &mut Rng) -> Vec<Point3<f64>> {
    let (lo, hi) = scene.infrastructure_bounds();
    let near = |p: &Point3<f64>| {
        p.x > lo.x - 12.0 && p.x < hi.x + 12.0 && p.y > lo.y - 12.0 && p.y < hi.y + 12.0
    };
    let mut points = Vec::new();
    for (t, tri) in scene.triangles.iter().enumerate() {
        let density = match scene.class(t as u32) {
            Class::Infrastructure => 150.0,
            Class::Obstacle => 60.0,
            Class::Ground => 6.0,
        };
        let expected = area(tri) * density;
        let count = expected.floor() as usize + usize::from(rng.uniform() < expected.fract());
        for _ in 0..count {
            let (mut s, mut r) = (rng.uniform(), rng.uniform());
            if s + r > 1.0 {
                (s, r) = (1.0 - s, 1.0 - r);
            }
            let p = tri[0] + (tri[1] - tri[0]) * s + (tri[2] - tri[0]) * r;
            if !near(&p) {
                continue;
            }
            let jitter = Vector3::new(rng.normal(), rng.normal(), rng.normal()) * 0.015;
            points.push(spalls.sunk(p) + jitter);
        }
    }
    points
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(flags: &[&str]) -> Result<SimOptions, clap::Error> {
        let command = <SimOptions as clap::Args>::augment_args(clap::Command::new("simulate"));
        let args = ["simulate", "--out", "flight"].iter().chain(flags);
        let matches = command.try_get_matches_from(args)?;
        <SimOptions as clap::FromArgMatches>::from_arg_matches(&matches)
    }

    #[test]
    fn the_default_flight_is_the_flags_defaults() {
        let o = SimOptions::new("flight".into());
        assert_eq!(o.out, Path::new("flight"));
        assert_eq!((o.scene, o.mesh.as_ref()), (BuiltIn::GirderBridge, None));
        assert_eq!(
            (
                o.seed,
                o.frames,
                o.width,
                o.height,
                o.cracks,
                o.crack_patterns
            ),
            (1, 300, 640, 480, 40, 0)
        );
        assert!(o.distortion && !o.distractors && !o.gimbal);
        assert_eq!((o.focal_px, o.standoff_m), (None, planner::STANDOFF));
        assert_eq!(o.image_format, ImageFormat::Jpeg);
        assert_eq!(o.surface, render::Surface::Smooth);
        assert_eq!(o.lens_blur_px, 0.6);
        // The yaw noise given in degrees comes back to the radians exactly.
        assert_eq!(o.pose_noise.position_m, flight::POSITION_NOISE);
        assert_eq!(o.pose_noise.yaw_rad, flight::YAW_NOISE);
        assert!(o.repeat.is_none() && o.crack_widths.is_none() && o.gps.is_none());
        assert_eq!(
            (o.pattern_widths.min_mm, o.pattern_widths.max_mm),
            (0.4, 1.0)
        );
        assert_eq!(o.sorties.recordings(), 1);
        assert!(!o.sorties.team() && o.sorties.offset.is_none() && !o.sorties.camera_only);
    }

    #[test]
    fn flags_set_their_options_and_need_what_they_say() {
        let o = parse(&[
            "--textured",
            "--no-distortion",
            "--drones",
            "3",
            "--yaw-noise",
            "90",
            "--lens-blur",
            "0",
        ])
        .unwrap();
        assert_eq!(o.lens_blur_px, 0.0);
        assert_eq!(o.surface, render::Surface::Textured);
        assert!(!o.distortion);
        assert_eq!((o.sorties.recordings(), o.sorties.team()), (3, true));
        assert_eq!(o.pose_noise.yaw_rad, std::f64::consts::FRAC_PI_2);
        let o = parse(&["--repeat-of", "earlier", "--new", "2"]).unwrap();
        let repeat = o.repeat.expect("a repeat");
        assert_eq!(
            (repeat.of.as_path(), repeat.grow, repeat.new),
            (Path::new("earlier"), 0.2, 2)
        );
        assert!(
            parse(&["--grow", "0.5"]).is_err(),
            "--grow needs --repeat-of"
        );
        assert!(parse(&["--drones", "2", "--sorties", "3"]).is_err());
        assert!(
            parse(&["--camera-only"]).is_err(),
            "--camera-only needs --sortie-offset"
        );
        assert!(parse(&["--scene", "tower", "--mesh", "m.obj"]).is_err());
    }
}
