//! The follow-up flight in the formats ground stations load, placed on the
//! Earth by a geo origin: a QGroundControl mission per sortie (MAVLink
//! items PX4 and ArduPilot fly), KML for Google Earth and GeoJSON.
//!
//! A mission takes off straight up to the sortie's first path point, flies
//! every point of the collision-checked path, and at each inspection
//! waypoint turns the gimbal (before arriving), hovers facing the gap and
//! takes one photo; it ends back at home and lands. Mission altitudes are
//! relative to the take-off point (MAVLink's relative frame), so they do
//! not depend on the altitude datum; KML and GeoJSON carry absolute
//! altitudes in the datum of the origin's altitude. A mission's geofence
//! holds the keep-out zones that are columns (a geofence polygon keeps out
//! at every altitude).

use nalgebra::Point3;
use postflight_core::geo::{GeoOrigin, Geodetic};
use postflight_core::outputs::replan::{Sortie, Waypoint};
use postflight_core::plan::PointKind;
use postflight_core::plan::path_csv::PathRow;
use postflight_core::region::Region;
use serde_json::{Value, json};

use crate::wpml::DjiAircraft;

/// MAVLink commands (`MAV_CMD`) and frames the missions use.
mod mavlink {
    pub const NAV_WAYPOINT: u16 = 16;
    pub const NAV_LAND: u16 = 21;
    pub const NAV_TAKEOFF: u16 = 22;
    pub const DO_MOUNT_CONTROL: u16 = 205;
    pub const IMAGE_START_CAPTURE: u16 = 2000;
    /// `MAV_FRAME_MISSION`: the item has no position.
    pub const FRAME_MISSION: u8 = 2;
    /// `MAV_FRAME_GLOBAL_RELATIVE_ALT`: altitude above home.
    pub const FRAME_RELATIVE_ALT: u8 = 3;
    /// `MAV_MOUNT_MODE_MAVLINK_TARGETING`.
    pub const MOUNT_MODE_TARGETING: f64 = 2.0;
    /// `MAV_TYPE_QUADROTOR`.
    pub const VEHICLE_QUADROTOR: u8 = 2;
    /// `MAV_AUTOPILOT_GENERIC`: the mission uses only common commands.
    pub const AUTOPILOT_GENERIC: u8 = 0;
}

/// What the ground-station files need besides the sorties.
pub struct Placement {
    pub origin: GeoOrigin,
    /// Where the team's first drone takes off: the geofence's altitude.
    pub launch: Point3<f64>,
    /// Hover at each inspection waypoint, seconds.
    pub hover_s: f64,
    pub speed_m_s: f64,
    /// The least climb of the take-off (the clearance), metres.
    pub min_takeoff_m: f64,
    /// Keep-out zones the missions' geofence holds (columns, as
    /// geofences keep out of a polygon at every altitude).
    pub fence: Vec<Region>,
    /// The aircraft the DJI missions are for.
    pub dji_aircraft: DjiAircraft,
}

impl Placement {
    fn geodetic(&self, p: &[f64; 3]) -> Geodetic {
        self.origin.to_geodetic(&Point3::from(*p))
    }

    /// A QGroundControl plan file (format version 1) for one sortie of a
    /// drone taking off from `launch` (its altitudes are above it).
    pub fn mission(&self, sortie: &Sortie, launch: Point3<f64>) -> Value {
        let home = self.origin.to_geodetic(&launch);
        let mut items = Items::new(home.altitude_m);
        let first = sortie.path.first().copied().unwrap_or(launch.into());
        let climb = self.geodetic(&first).altitude_m - home.altitude_m;
        items.takeoff(&home, climb.max(self.min_takeoff_m));
        // The path starts at home, where the take-off ends.
        for step in steps(sortie).into_iter().skip(1) {
            let at = self.geodetic(&step.point);
            let heading = Some(self.origin.heading_deg(step.yaw));
            match step.waypoint {
                Some(w) => {
                    items.command(
                        mavlink::DO_MOUNT_CONTROL,
                        [
                            Some(-w.gimbal_pitch.to_degrees()),
                            Some(0.0),
                            Some(0.0),
                            Some(0.0),
                            Some(0.0),
                            Some(0.0),
                            Some(mavlink::MOUNT_MODE_TARGETING),
                        ],
                    );
                    items.waypoint(&at, self.hover_s, heading);
                    items.command(
                        mavlink::IMAGE_START_CAPTURE,
                        [Some(0.0), Some(0.0), Some(1.0), Some(0.0), None, None, None],
                    );
                }
                None => items.waypoint(&at, 0.0, heading),
            }
        }
        items.land(&home);
        json!({
            "fileType": "Plan",
            "version": 1,
            "groundStation": "QGroundControl",
            "mission": {
                "version": 2,
                "firmwareType": mavlink::AUTOPILOT_GENERIC,
                "vehicleType": mavlink::VEHICLE_QUADROTOR,
                "cruiseSpeed": self.speed_m_s,
                "hoverSpeed": self.speed_m_s,
                "globalPlanAltitudeMode": 1,
                "plannedHomePosition": [home.latitude_deg, home.longitude_deg, home.altitude_m],
                "items": items.items,
            },
            "geoFence": {"circles": [], "polygons": self.fence_polygons(), "version": 2},
            "rallyPoints": {"points": [], "version": 2},
        })
    }

    /// The keep-out zones as the geofence's exclusion polygons, corners as
    /// `[latitude, longitude]`.
    fn fence_polygons(&self) -> Vec<Value> {
        self.fence
            .iter()
            .map(|zone| {
                let corners: Vec<[f64; 2]> = zone
                    .outline
                    .iter()
                    .map(|[x, y]| {
                        let g = self.geodetic(&[*x, *y, self.launch.z]);
                        [g.latitude_deg, g.longitude_deg]
                    })
                    .collect();
                json!({"inclusion": false, "polygon": corners, "version": 1})
            })
            .collect()
    }

    /// GeoJSON (RFC 7946): each sortie's path as a LineString and each
    /// inspection waypoint as a Point, `[longitude, latitude, altitude]`.
    pub fn geojson(&self, sorties: &[Sortie]) -> Value {
        let mut features = Vec::new();
        for (s, sortie) in sorties.iter().enumerate() {
            let line: Vec<[f64; 3]> = sortie
                .path
                .iter()
                .map(|p| lon_lat_alt(&self.geodetic(p)))
                .collect();
            let mut properties =
                json!({"sortie": s + 1, "length_m": sortie.length_m, "time_s": sortie.time_s});
            if team(sorties) {
                properties["drone"] = json!(sortie.drone + 1);
            }
            features.push(json!({
                "type": "Feature",
                "geometry": {"type": "LineString", "coordinates": line},
                "properties": properties,
            }));
            for (k, w) in sortie.waypoints.iter().enumerate() {
                features.push(json!({
                    "type": "Feature",
                    "geometry": {"type": "Point", "coordinates": lon_lat_alt(&self.geodetic(&[w.x, w.y, w.z]))},
                    "properties": {
                        "sortie": s + 1,
                        "waypoint": k + 1,
                        "heading_deg": self.origin.heading_deg(w.yaw),
                        "gimbal_pitch_deg": w.gimbal_pitch.to_degrees(),
                        "gap_voxels": w.gap_voxels.len(),
                    },
                }));
            }
        }
        json!({"type": "FeatureCollection", "features": features})
    }

    /// KML 2.2: a folder per sortie with its path and its waypoints, at
    /// absolute altitudes.
    pub fn kml(&self, sorties: &[Sortie]) -> String {
        let mut folders = String::new();
        for (s, sortie) in sorties.iter().enumerate() {
            let path: Vec<String> = sortie
                .path
                .iter()
                .map(|p| kml_coordinates(&self.geodetic(p)))
                .collect();
            let n = match team(sorties) {
                true => format!("{} (drone {})", s + 1, sortie.drone + 1),
                false => (s + 1).to_string(),
            };
            folders += &format!(
                "<Folder><name>Sortie {n}</name>\n<Placemark><name>Sortie {n} path</name><styleUrl>#path</styleUrl><LineString><altitudeMode>absolute</altitudeMode><coordinates>{}</coordinates></LineString></Placemark>\n",
                path.join(" "),
            );
            for (k, w) in sortie.waypoints.iter().enumerate() {
                folders += &format!(
                    "<Placemark><name>{}.{}</name><description>heading {:.0} deg, gimbal pitch {:.0} deg down, {} gap voxels</description><Point><altitudeMode>absolute</altitudeMode><coordinates>{}</coordinates></Point></Placemark>\n",
                    s + 1,
                    k + 1,
                    self.origin.heading_deg(w.yaw),
                    w.gimbal_pitch.to_degrees(),
                    w.gap_voxels.len(),
                    kml_coordinates(&self.geodetic(&[w.x, w.y, w.z]))
                );
            }
            folders += "</Folder>\n";
        }
        format!(
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<kml xmlns=\"http://www.opengis.net/kml/2.2\">\n<Document><name>postflight follow-up flight</name>\n<Style id=\"path\"><LineStyle><color>ff00a5ff</color><width>3</width></LineStyle></Style>\n{folders}</Document>\n</kml>\n"
        )
    }
}

/// A point of a sortie's path as flown: its yaw (the waypoint being flown
/// to, as `replan.csv` gives it) and the inspection waypoint there, if any.
pub(crate) struct Step<'a> {
    pub(crate) point: [f64; 3],
    pub(crate) yaw: f64,
    /// Radians, positive looking down, as the yaw.
    pub(crate) gimbal_pitch: f64,
    pub(crate) waypoint: Option<&'a Waypoint>,
}

/// Every point of the path, home to home, each inspection waypoint once
/// (waypoints sharing a point are turned to there, one step each).
pub(crate) fn steps(sortie: &Sortie) -> Vec<Step<'_>> {
    let mut steps = Vec::new();
    let mut next = 0;
    for p in &sortie.path {
        let mut at_waypoint = false;
        while let Some(w) = sortie.waypoints.get(next).filter(|w| [w.x, w.y, w.z] == *p) {
            steps.push(Step {
                point: *p,
                yaw: w.yaw,
                gimbal_pitch: w.gimbal_pitch,
                waypoint: Some(w),
            });
            next += 1;
            at_waypoint = true;
        }
        if !at_waypoint {
            let toward = sortie.waypoints.get(next).or(sortie.waypoints.last());
            steps.push(Step {
                point: *p,
                yaw: toward.map_or(0.0, |w| w.yaw),
                gimbal_pitch: toward.map_or(0.0, |w| w.gimbal_pitch),
                waypoint: None,
            });
        }
    }
    steps
}

/// `replan.csv`: every point of every sortie's path, home to home
/// ([`PathRow`]: GATSBI's `X,Y,Z,Yaw` inspection path, then the gimbal
/// pitch, the sortie and what the point is). Comment lines above the
/// header give the frame and the units.
pub fn path_csv(sorties: &[Sortie], frame_id: &str) -> String {
    let comments = format!(
        "# postflight follow-up flight: {} sortie{}, taking off from and landing at home\n\
         # frame: {frame_id} (the SLAM map's), z up; X, Y, Z in metres\n\
         # Yaw: radians, counter-clockwise from the x axis (REP 103); GimbalPitch: degrees, negative looking down\n",
        sorties.len(),
        if sorties.len() == 1 { "" } else { "s" },
    );
    let mut rows = Vec::new();
    for (sortie, flown) in (1..).zip(sorties) {
        let steps = steps(flown);
        let last = steps.len().saturating_sub(1);
        rows.extend(steps.iter().enumerate().map(|(i, step)| {
            let [x, y, z] = step.point;
            PathRow {
                x,
                y,
                z,
                yaw: step.yaw,
                gimbal_pitch_deg: -step.gimbal_pitch.to_degrees(),
                sortie,
                point: match step.waypoint {
                    Some(_) => PointKind::Waypoint,
                    None if i == 0 || i == last => PointKind::Home,
                    None => PointKind::Transit,
                },
            }
        }));
    }
    // Numbers, and kinds by their names, always make a table.
    postflight_core::plan::path_csv::path_csv(&comments, &rows).expect("a path's rows are a table")
}

/// Whether the sorties are a team's (flown by more than one drone).
fn team(sorties: &[Sortie]) -> bool {
    sorties.iter().any(|s| s.drone > 0)
}

/// Mission items in order, numbered from 1.
struct Items {
    items: Vec<Value>,
    home_altitude_m: f64,
}

impl Items {
    fn new(home_altitude_m: f64) -> Self {
        Self {
            items: Vec::new(),
            home_altitude_m,
        }
    }

    fn push(&mut self, command: u16, frame: u8, params: [Option<f64>; 7], altitude: Option<f64>) {
        let mut item = json!({
            "type": "SimpleItem",
            "autoContinue": true,
            "command": command,
            "doJumpId": self.items.len() + 1,
            "frame": frame,
            "params": params,
        });
        if let Some(altitude) = altitude {
            item["Altitude"] = json!(altitude);
            item["AltitudeMode"] = json!(1);
            item["AMSLAltAboveTerrain"] = Value::Null;
        }
        self.items.push(item);
    }

    fn command(&mut self, command: u16, params: [Option<f64>; 7]) {
        self.push(command, mavlink::FRAME_MISSION, params, None);
    }

    fn positioned(&mut self, command: u16, at: &Geodetic, first: [Option<f64>; 4], altitude: f64) {
        let [p1, p2, p3, p4] = first;
        let params = [
            p1,
            p2,
            p3,
            p4,
            Some(at.latitude_deg),
            Some(at.longitude_deg),
            Some(altitude),
        ];
        self.push(command, mavlink::FRAME_RELATIVE_ALT, params, Some(altitude));
    }

    fn takeoff(&mut self, home: &Geodetic, altitude: f64) {
        let params = [Some(0.0), Some(0.0), Some(0.0), None];
        self.positioned(mavlink::NAV_TAKEOFF, home, params, altitude);
    }

    fn waypoint(&mut self, at: &Geodetic, hold_s: f64, heading_deg: Option<f64>) {
        let params = [Some(hold_s), Some(0.0), Some(0.0), heading_deg];
        let altitude = at.altitude_m - self.home_altitude_m;
        self.positioned(mavlink::NAV_WAYPOINT, at, params, altitude);
    }

    fn land(&mut self, home: &Geodetic) {
        let params = [Some(0.0), Some(0.0), Some(0.0), None];
        self.positioned(mavlink::NAV_LAND, home, params, 0.0);
    }
}

fn lon_lat_alt(g: &Geodetic) -> [f64; 3] {
    [g.longitude_deg, g.latitude_deg, g.altitude_m]
}

fn kml_coordinates(g: &Geodetic) -> String {
    format!(
        "{:.9},{:.9},{:.3}",
        g.longitude_deg, g.latitude_deg, g.altitude_m
    )
}
