//! The stage's settings, declared once: the `[replan]` table of
//! `postflight.toml` and the flags of `postflight replan`.

use postflight_core::geo::{GeoOrigin, geo_origin_values};
use std::path::PathBuf;

use postflight_core::InvalidSetting;
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

/// The most clearance a follow-up flight may keep from the structure,
/// metres: inspection drones keep 1 to 5 m, and the free space's distances
/// are worked out that far round every occupied voxel.
pub const MAX_CLEARANCE_M: f64 = 10.0;

/// The most drones one follow-up is split between: teams fly a handful,
/// and the tour's split grows with each.
pub const MAX_DRONES: u32 = 50;

impl ReplanConfig {
    /// Refuse settings that cannot work, each named as given, with the
    /// limits that keep the plan's work bounded.
    pub fn check(&self) -> Result<(), InvalidSetting> {
        self.check_flying()?;
        self.check_team()?;
        if let Some(o) = &self.geo_origin {
            InvalidSetting::check(
                o.check().is_ok(),
                keys::geo_origin,
                format!("{}, {}", o.position.latitude_deg, o.position.longitude_deg),
                "a latitude within ±90 and a longitude within ±180 degrees, all finite",
            )?;
        }
        Ok(())
    }

    /// How the drones fly: clearance, hover, battery, speed, sorties, the
    /// gimbal and the ceiling.
    fn check_flying(&self) -> Result<(), InvalidSetting> {
        let s = self;
        InvalidSetting::check(
            (0.0..=MAX_CLEARANCE_M).contains(&s.clearance_m),
            keys::clearance_m,
            s.clearance_m,
            &format!(
                "0 to {MAX_CLEARANCE_M} metres (the free space is searched that far round the map)"
            ),
        )?;
        InvalidSetting::check(
            s.hover_s.is_finite() && s.hover_s >= 0.0,
            keys::hover_s,
            s.hover_s,
            "0 or more seconds",
        )?;
        InvalidSetting::check(
            s.battery_minutes.is_finite() && s.battery_minutes > 0.0,
            keys::battery_minutes,
            s.battery_minutes,
            "a positive number of minutes",
        )?;
        InvalidSetting::check(
            s.speed_m_s.is_finite() && s.speed_m_s > 0.0,
            keys::speed_m_s,
            s.speed_m_s,
            "a positive number of metres per second",
        )?;
        if let Some(m) = s.max_sortie_length_m {
            InvalidSetting::check(
                m > 0.0,
                keys::max_sortie_length_m,
                m,
                "a positive number of metres",
            )?;
        }
        InvalidSetting::check(
            (0.0..=90.0).contains(&s.max_gimbal_up_deg),
            keys::max_gimbal_up_deg,
            s.max_gimbal_up_deg,
            "between 0 and 90 degrees",
        )?;
        if let Some(c) = s.ceiling_m {
            InvalidSetting::check(
                c > 0.0,
                keys::ceiling_m,
                c,
                "a positive number of metres above the take-off point",
            )?;
        }
        Ok(())
    }

    /// The team: how many drones, the home, and each `[[replan.drone]]`.
    fn check_team(&self) -> Result<(), InvalidSetting> {
        let s = self;
        InvalidSetting::check(
            (1..=MAX_DRONES).contains(&s.drones),
            keys::drones,
            s.drones,
            &format!("1 to {MAX_DRONES} drones"),
        )?;
        if let Some(h) = s.home {
            InvalidSetting::check(
                h.iter().all(|v| v.is_finite()),
                keys::home,
                format!("[{}, {}, {}]", h[0], h[1], h[2]),
                "a point [x, y, z] in the map frame, metres",
            )?;
        }
        if !s.drone.is_empty() {
            InvalidSetting::check(
                s.drones == 1 || s.drones as usize == s.drone.len(),
                keys::drones,
                s.drones,
                &format!(
                    "1 or the number of {} entries ({}), which give the team",
                    keys::drone,
                    s.drone.len()
                ),
            )?;
        }
        InvalidSetting::check(
            s.drone.len() <= MAX_DRONES as usize,
            keys::drone,
            format!("{} entries", s.drone.len()),
            &format!("1 to {MAX_DRONES} drones"),
        )?;
        for d in &s.drone {
            if let Some(h) = d.home {
                InvalidSetting::check(
                    h.iter().all(|v| v.is_finite()),
                    keys::drone,
                    format!("{}'s home [{}, {}, {}]", d.name, h[0], h[1], h[2]),
                    "a point [x, y, z] in the map frame, metres",
                )?;
            }
            let positive = |v: Option<f64>| v.is_none_or(|v| v.is_finite() && v > 0.0);
            for (what, v) in [
                ("speed_m_s", d.speed_m_s),
                ("battery_minutes", d.battery_minutes),
            ] {
                let value = format!("{}'s {what} {}", d.name, v.unwrap_or_default());
                InvalidSetting::check(positive(v), keys::drone, value, "positive")?;
            }
        }
        Ok(())
    }
}
