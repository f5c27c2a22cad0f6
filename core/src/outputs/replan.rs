//! What the replan stage writes: the follow-up flight as `replan.json`
//! (its summary, and also an inspection plan `postflight coverage
//! --viewpoints` can check) and `replan.csv` (GATSBI's `X,Y,Z,Yaw`
//! inspection path).

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::geo::GeoOrigin;
use crate::map::VoxelIndex;
use crate::plan::Viewpoint;
use crate::region::Region;
use crate::view::ViewModel;

/// Files of the replan stage.
pub mod files {
    /// Its summary: the follow-up flight.
    pub const SUMMARY: &str = "replan.json";
    pub const PATH_CSV: &str = "replan.csv";
    /// The follow-up flight on the Earth (with a geo origin).
    pub const KML: &str = "replan.kml";
    pub const GEOJSON: &str = "replan.geojson";

    /// The formats a sortie's mission is written in, by file extension.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum Mission {
        /// A QGroundControl plan (`.plan`): PX4 and ArduPilot.
        QGroundControl,
        /// A DJI WPML waypoint mission (`.kmz`): DJI Pilot 2, FlightHub 2.
        DjiWpml,
    }

    impl Mission {
        pub const ALL: [Self; 2] = [Self::QGroundControl, Self::DjiWpml];

        pub fn extension(self) -> &'static str {
            match self {
                Self::QGroundControl => "plan",
                Self::DjiWpml => "kmz",
            }
        }
    }

    /// A sortie's mission: `replan.plan` (or `.kmz`) when the flight is one
    /// sortie, else `replan-1.plan`, `replan-2.plan`, ...
    pub fn mission(sortie: usize, sorties: usize, format: Mission) -> String {
        let extension = format.extension();
        if sorties == 1 {
            format!("replan.{extension}")
        } else {
            format!("replan-{}.{extension}", sortie + 1)
        }
    }

    /// A team drone's sortie's mission: `replan-drone-2.plan` when the
    /// drone flies one sortie, else `replan-drone-2-1.plan`, ...
    pub fn drone_mission(drone: usize, sortie: usize, sorties: usize, format: Mission) -> String {
        let extension = format.extension();
        if sorties == 1 {
            format!("replan-drone-{}.{extension}", drone + 1)
        } else {
            format!("replan-drone-{}-{}.{extension}", drone + 1, sortie + 1)
        }
    }

    /// A team drone's path, as `replan.csv` holds the team's.
    pub fn drone_path_csv(drone: usize) -> String {
        format!("replan-drone-{}.csv", drone + 1)
    }

    /// Whether a file in the run directory is a team drone's path.
    pub fn is_drone_path_csv(name: &str) -> bool {
        name.starts_with("replan-drone-") && name.ends_with(".csv")
    }

    /// Whether a file in the run directory is a sortie's mission.
    pub fn is_mission(name: &str) -> bool {
        let extension = name.rsplit_once('.').map(|(_, e)| e);
        name.starts_with("replan")
            && Mission::ALL
                .iter()
                .any(|m| extension == Some(m.extension()))
    }
}

/// A stop of the follow-up flight.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Waypoint {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    /// Heading about world z, radians (ROS: counter-clockwise from x).
    pub yaw: f64,
    /// Gimbal pitch, radians, positive looking down.
    pub gimbal_pitch: f64,
    /// Gap voxels inspected here (each gap voxel at exactly one waypoint).
    pub gap_voxels: Vec<VoxelIndex>,
}

/// One flight from home and back.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Sortie {
    /// The drone of the team that flies it, from 0 (0 for one drone).
    #[serde(default)]
    pub drone: u32,
    pub waypoints: Vec<Waypoint>,
    /// The collision-free path flown, home to home.
    pub path: Vec<[f64; 3]>,
    pub length_m: f64,
    /// Flying at the given speed plus hovering at each waypoint.
    pub time_s: f64,
}

/// One drone's share of a team's follow-up flight.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DronePlan {
    /// From 0, as its sorties' `drone`.
    pub drone: u32,
    /// As `[[replan.drone]]` names it (`drone K` for drones alike).
    #[serde(default)]
    pub name: String,
    /// Where it takes off and lands, map frame.
    #[serde(default)]
    pub home: [f64; 3],
    #[serde(default)]
    pub speed_m_s: f64,
    #[serde(default)]
    pub battery_minutes: f64,
    /// Its camera's calibration file; `None`: the flight's camera.
    #[serde(default)]
    pub camera: Option<PathBuf>,
    /// Its camera's image width and height and focal length, pixels.
    #[serde(default)]
    pub image_size: [u32; 2],
    #[serde(default)]
    pub focal_px: f64,
    pub sorties: usize,
    pub waypoints: usize,
    pub length_m: f64,
    /// Its sorties one after the other, seconds.
    pub time_s: f64,
    /// When it takes off, seconds after the team's first drone: staggered
    /// so that no two drones come closer than the clearance.
    #[serde(default)]
    pub takeoff_s: f64,
}

/// A gap voxel the follow-up flight cannot inspect, and why.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Uninspectable {
    pub voxel: VoxelIndex,
    pub reason: Unplannable,
}

/// Why a gap voxel is left out of the follow-up flight.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Unplannable {
    /// No viewpoint that keeps the clearance inspects it.
    NoClearViewpoint,
    /// Such viewpoints exist, but no collision-free path leads to them from home.
    Unreachable,
    /// Fewer such viewpoints than the views it needs.
    TooFewViewpoints,
}

/// Which gaps a follow-up flight goes back for.
#[derive(
    Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize, clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum GapChoice {
    /// The planned voxels the flight missed (every gap when no plan says
    /// which were planned), and the candidates to re-shoot.
    #[default]
    Missed,
    /// Every gap voxel, planned or not, and the candidates to re-shoot.
    All,
    /// Only the candidates to re-shoot.
    Reshoot,
}

impl GapChoice {
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Missed => "missed",
            Self::All => "all",
            Self::Reshoot => "reshoot",
        }
    }
}

/// A defect candidate whose evidence is weak, flown again.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReshootSpot {
    /// The candidate's id.
    pub defect: String,
    /// The voxel it is on.
    pub voxel: VoxelIndex,
}

/// `replan.json`. Its first fields make it an inspection plan (the gap
/// voxels it inspects as targets, the waypoints as viewpoints in flight
/// order), so `postflight coverage --viewpoints replan.json` checks it.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ReplanSummary {
    pub frame_id: String,
    pub resolution: f64,
    pub origin: [f64; 3],
    pub target_voxels: Vec<VoxelIndex>,
    pub viewpoints: Vec<Viewpoint>,
    pub view: ViewModel,
    pub run: PathBuf,
    pub home: [f64; 3],
    pub clearance_m: f64,
    pub speed_m_s: f64,
    pub hover_s: f64,
    pub max_sortie_length_m: Option<f64>,
    /// One battery's flight time, the sorties' limit, minutes.
    pub battery_minutes: f64,
    /// Which gaps were chosen.
    pub gaps: GapChoice,
    /// The keep-out zones every viewpoint and path point is outside, in the
    /// map frame (from the settings and the zones file).
    #[serde(default)]
    pub keep_out: Vec<Region>,
    /// The ceiling every point is below, map z (metres).
    #[serde(default)]
    pub ceiling_z_m: Option<f64>,
    /// Gap voxels coverage found (not inspected, not uninspectable).
    pub coverage_gap_voxels: usize,
    /// The voxels chosen to fly for: gaps as `gaps` chose them, and the
    /// re-shoot spots' voxels.
    pub gap_voxels: usize,
    /// Candidates to re-shoot among them.
    pub reshoot_spots: Vec<ReshootSpot>,
    /// Of the chosen voxels, the ones this plan inspects.
    pub planned_gap_voxels: usize,
    pub uninspectable_gaps: Vec<Uninspectable>,
    pub candidate_viewpoints: usize,
    /// Viewpoints a greedy set cover needs to inspect every chosen voxel
    /// the candidates inspect: the tour picks its waypoints among these.
    pub set_cover_viewpoints: usize,
    /// Of `time_s`: hovering at waypoints, and flying, seconds.
    pub hover_time_s: f64,
    pub travel_time_s: f64,
    /// Drone by drone, each drone's in flying order.
    pub sorties: Vec<Sortie>,
    pub waypoints: usize,
    pub length_m: f64,
    /// Every sortie's time added up, seconds.
    pub time_s: f64,
    /// The team: each drone's share (one entry for one drone).
    #[serde(default)]
    pub drones: Vec<DronePlan>,
    /// The mission's duration: from the first take-off to the last
    /// landing (each drone flying its sorties one after the other), seconds.
    #[serde(default)]
    pub mission_time_s: f64,
    /// The closest two drones of a team come while flying, metres (`None`
    /// for one drone).
    #[serde(default)]
    pub closest_drones_m: Option<f64>,
    pub solver: Option<ReplanSolverStats>,
    /// Where the stage's time went.
    #[serde(default)]
    pub phases: ReplanPhases,
    /// The map frame on the Earth, if known: from the settings, or the
    /// flight's GPS fixes (`geo_origin_from` says which).
    #[serde(default)]
    pub geo_origin: Option<GeoOrigin>,
    #[serde(default)]
    pub geo_origin_from: Option<String>,
    /// Missions, KML and GeoJSON written beside `replan.json` (with a geo
    /// origin and a flight to fly).
    #[serde(default)]
    pub ground_station_files: Vec<String>,
    pub seconds: f64,
    pub warnings: Vec<String>,
}

/// Where the replan stage's time went, seconds (`seconds` also counts
/// reading the inputs and writing the outputs).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ReplanPhases {
    /// Inflating the map by the clearance and clearing home.
    pub clearance_s: f64,
    /// Drawing candidate viewpoints, judging them under the View model, the
    /// set cover and the clusters.
    pub viewpoints_s: f64,
    /// GTSP solves and repairs.
    pub solve_s: f64,
    /// Collision-free paths of the legs, and splitting the tour into sorties.
    pub paths_s: f64,
    /// Solves: the first, then one repair per lazy collision check that
    /// re-costed a leg.
    pub rounds: usize,
}

/// What the GTSP search of the first solve did (the solver's own
/// statistics, as `replan.json` records them).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct FirstSolve {
    /// Worker threads.
    pub threads: usize,
    /// Searches from a starting tour.
    pub trials: usize,
    pub rounds: usize,
    pub iterations: u64,
    /// Cost of the best tour of the first cold trial's starting tour
    /// (centimetres of straight-line flight).
    pub initial_cost: i64,
    /// Seconds until the returned tour was first found.
    pub best_found_s: f64,
    pub time_s: f64,
    /// The search was cut by the time limit.
    pub timed_out: bool,
}

/// What the solver and the collision checks did.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ReplanSolverStats {
    pub vertices: usize,
    /// Clusters of the GTSP: gap voxels that the same viewpoints inspect are
    /// one cluster, and a voxel inspected from every viewpoint of another's
    /// cluster needs none (serving that one serves it).
    pub clusters: usize,
    /// Solves: the first with straight-line costs, then, after each lazy
    /// collision check that re-costed a leg, a repair of the last tour
    /// (every fifth round a full solve with the costs learnt so far).
    pub rounds: usize,
    /// Legs given a collision-free path.
    pub legs_checked: usize,
    /// Legs whose path was over the detour limit, re-costed.
    pub legs_recosted: usize,
    /// The last solve's tour had no leg over the detour limit (false: the
    /// round limit was reached and that tour is flown as it is).
    pub converged: bool,
    /// The first solve's statistics.
    pub first_solve: FirstSolve,
    /// Solving and collision checks, seconds.
    pub solve_seconds: f64,
    /// Of `solve_seconds`, finding the legs' collision-free paths.
    #[serde(default)]
    pub paths_seconds: f64,
}
