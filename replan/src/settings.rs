//! The stage's settings, declared once: the `[replan]` table of
//! `postflight.toml` and the flags of `postflight replan`.

use postflight_core::geo::{GeoOrigin, geo_origin_values};
use std::path::PathBuf;

use postflight_core::outputs::replan::GapChoice;
use postflight_core::region::Region;
use postflight_core::setting::point3;

/// One drone of a team, as `[[replan.drone]]` gives it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Drone {
    /// As the plan and the report name it.
    pub name: String,
    /// Take-off and landing point, metres in the map frame [default:
    /// `[replan] home`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub home: Option<[f64; 3]>,
    /// Cruise speed, m/s [default: `[replan] speed_m_s`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed_m_s: Option<f64>,
    /// One battery's flight time, minutes [default: `[replan]
    /// battery_minutes`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub battery_minutes: Option<f64>,
    /// Its camera's calibration, a ROS camera_info YAML (as
    /// `camera_calibration` writes it) [default: the flight's camera].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera_info_file: Option<PathBuf>,
}

postflight_core::inline_table_setting!(
    Drone,
    "a drone {name = \"...\", home = [x, y, z], speed_m_s = ..., battery_minutes = ..., camera_info_file = \"...\"}"
);

postflight_core::settings! {
    table = "replan", keys = keys;
    /// `[replan]`: the follow-up flight's vehicle, battery and solver.
    pub struct ReplanSettings =>
    /// How a replan plans the follow-up flight.
    struct ReplanConfig {
        /// Take-off and landing point, metres in the map frame [default:
        /// the flight's first pose].
        #[arg(long, value_name = "X,Y,Z", value_parser = point3, allow_hyphen_values = true)]
        home: [f64; 3],
        /// Closest approach to any occupied voxel, metres (0 to 10).
        #[arg(long = "clearance", value_name = "M")]
        clearance_m: f64 = 1.0,
        /// Which gaps to fly for: the planned voxels the flight missed,
        /// every gap, or only the candidates to re-shoot; the re-shoots
        /// always come too.
        #[arg(long, value_enum, value_name = "missed|all|reshoot")]
        gaps: GapChoice = GapChoice::Missed,
        /// One battery's flight time, minutes: each sortie (flying and
        /// hovering) fits in it. The default is a DJI Matrice 30T's rated
        /// 41 minutes less the reserve pilots keep for wind, the return and
        /// landing: about 60% of the rating.
        #[arg(long, value_name = "MIN")]
        battery_minutes: f64 = 25.0,
        /// Also keep each sortie from home no longer than this, metres.
        #[arg(long = "max-sortie-length", value_name = "M")]
        max_sortie_length_m: f64,
        /// Cruise speed for the time estimate, m/s.
        #[arg(long = "speed", value_name = "M/S")]
        speed_m_s: f64 = 2.0,
        /// Hover per waypoint for the time estimate, seconds.
        #[arg(long = "hover", value_name = "S")]
        hover_s: f64 = 2.0,
        /// Longest the tour's GTSP solve may take, seconds; it stops sooner
        /// when it converges, and gets 1 s plus 2 ms per cluster at most.
        #[arg(long = "solver-time-limit", value_name = "S")]
        solver_time_limit_s: f64 = 10.0,
        /// Drones flying the follow-up together, all from home: the tour is
        /// split among them so that the slowest is done soonest, each
        /// drone's share flown in battery sorties.
        #[arg(long, value_name = "N")]
        drones: u32 = 1,
        /// The team drone by drone, when they differ: each a `name` and,
        /// where it is not the `[replan]` one, its `home`, `speed_m_s`,
        /// `battery_minutes` and camera (`camera_info_file`, a ROS
        /// calibration YAML; default: the flight's camera). Its share of
        /// the gaps is planned from its home with its camera.
        /// `[[replan.drone]]` tables, or the flag once per drone as a TOML
        /// inline table; replaces `drones`.
        #[arg(long = "drone", value_name = "DRONE")]
        drone: Vec<Drone> = Vec::new(),
        /// Keep-out zones in the map frame, each a region (`name`,
        /// `outline` of `[x, y]` corners, optional `bottom_m` and `top_m`,
        /// map z): no viewpoint or path point of the follow-up is inside
        /// one. `[[replan.keep_out]]` tables, or the flag once per zone as
        /// a TOML inline table.
        #[arg(long = "keep-out-zone", value_name = "REGION")]
        keep_out: Vec<Region> = Vec::new(),
        /// More keep-out zones, as GeoJSON polygons on the Earth with their
        /// altitude bands (EUROCAE ED-269 properties), placed by the geo
        /// origin.
        #[arg(long = "keep-out", value_name = "ZONES.geojson")]
        keep_out_file: PathBuf,
        /// Highest the drones may fly, metres above the take-off point.
        #[arg(long = "ceiling", value_name = "M")]
        ceiling_m: f64,
        /// Solver seed.
        #[arg(long, value_name = "N")]
        seed: u64 = gtsp::SolveOptions::default().seed,
        /// The map frame on the Earth: its origin's latitude and longitude
        /// (degrees), altitude (metres) and the heading of its x axis from
        /// east, counter-clockwise (degrees, default 0); also writes the
        /// flight as QGroundControl and DJI missions, KML and GeoJSON
        /// [default: from the flight's GPS fixes or geotagged photos].
        #[arg(long, value_name = "LAT,LON,ALT[,YAW_DEG]", allow_hyphen_values = true)]
        #[serde(with = "geo_origin_values")]
        geo_origin: GeoOrigin,
        /// How far above the horizon the gimbal can look, degrees (a Mavic
        /// 3E's: 35): no waypoint looks up more.
        #[arg(long = "max-gimbal-up", value_name = "DEG")]
        max_gimbal_up_deg: f64 = 90.0,
        /// The DJI aircraft (and camera) the DJI waypoint missions
        /// (`replan.kmz`, WPML) are written for.
        #[arg(long, value_enum, value_name = "AIRCRAFT")]
        dji_aircraft: crate::wpml::DjiAircraft = crate::wpml::DjiAircraft::M3e,
    }
}
