//! The follow-up flight as DJI waypoint missions: a KMZ per sortie holding
//! `wpmz/template.kml` (the waypoint template DJI Pilot 2 and FlightHub 2
//! open and edit) and `wpmz/waylines.wpml` (the wayline the aircraft
//! executes), in DJI's published WPML (Waypoint Markup Language, KML with
//! the `wpml:` namespace).
//!
//! The mission flies every point of the sortie's collision-checked path,
//! as the QGroundControl missions do; at each inspection waypoint it
//! turns to the waypoint's heading (smoothly, on the way there), turns
//! the gimbal, hovers and takes a photo. Heights are relative to the
//! take-off point (`relativeToStartPoint`), so they do not depend on the
//! altitude datum; the take-off point itself is given as the mission's
//! reference point.

use std::fmt::Write as _;
use std::io::Write as _;

use nalgebra::Point3;
use postflight_core::geo::Geodetic;
use postflight_core::outputs::replan::Sortie;
use serde::{Deserialize, Serialize};

use crate::ground_station::{Placement, steps};

/// The WPML namespace, as DJI Pilot 2 writes it.
const NAMESPACE: &str = "http://www.dji.com/wpmz/1.0.2";
/// Where in the KMZ the two files are.
pub const TEMPLATE: &str = "wpmz/template.kml";
pub const WAYLINES: &str = "wpmz/waylines.wpml";
/// DJI's range for the take-off security height, metres.
const TAKEOFF_SECURITY_M: (f64, f64) = (1.2, 1500.0);

/// The DJI aircraft (and camera) the missions are for: WPML names both,
/// and DJI Pilot 2 opens a mission only for its aircraft.
#[derive(
    Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize, clap::ValueEnum,
)]
#[serde(rename_all = "kebab-case")]
pub enum DjiAircraft {
    /// Matrice 30 with its camera.
    M30,
    /// Matrice 30T with its camera.
    M30t,
    /// Mavic 3 Enterprise with its camera.
    #[default]
    M3e,
    /// Mavic 3 Thermal with its camera.
    M3t,
    /// Matrice 3D with its camera.
    M3d,
    /// Matrice 3TD with its camera.
    M3td,
    /// Matrice 350 RTK with a Zenmuse H20.
    #[value(name = "m350-h20")]
    #[serde(rename = "m350-h20")]
    M350H20,
    /// Matrice 350 RTK with a Zenmuse H20T.
    #[value(name = "m350-h20t")]
    #[serde(rename = "m350-h20t")]
    M350H20t,
    /// Matrice 350 RTK with a Zenmuse H30.
    #[value(name = "m350-h30")]
    #[serde(rename = "m350-h30")]
    M350H30,
    /// Matrice 350 RTK with a Zenmuse H30T.
    #[value(name = "m350-h30t")]
    #[serde(rename = "m350-h30t")]
    M350H30t,
    /// Matrice 300 RTK with a Zenmuse H20.
    #[value(name = "m300-h20")]
    #[serde(rename = "m300-h20")]
    M300H20,
    /// Matrice 300 RTK with a Zenmuse H20T.
    #[value(name = "m300-h20t")]
    #[serde(rename = "m300-h20t")]
    M300H20t,
}

impl DjiAircraft {
    /// `(droneEnumValue, droneSubEnumValue, payloadEnumValue)`, from DJI's
    /// enumeration values for aircraft and cameras.
    fn enums(self) -> (u32, u32, u32) {
        match self {
            Self::M30 => (67, 0, 52),
            Self::M30t => (67, 1, 53),
            Self::M3e => (77, 0, 66),
            Self::M3t => (77, 1, 67),
            Self::M3d => (91, 0, 80),
            Self::M3td => (91, 1, 81),
            Self::M350H20 => (89, 0, 42),
            Self::M350H20t => (89, 0, 43),
            Self::M350H30 => (89, 0, 82),
            Self::M350H30t => (89, 0, 83),
            Self::M300H20 => (60, 0, 42),
            Self::M300H20t => (60, 0, 43),
        }
    }
}

/// Write one sortie's mission as a KMZ (a zip of the two WPML files) into
/// `file`, for a drone taking off from `launch`.
pub fn write_kmz(
    file: &mut std::fs::File,
    placement: &Placement,
    sortie: &Sortie,
    launch: Point3<f64>,
) -> std::io::Result<()> {
    let mission = Mission::new(placement, sortie, launch);
    let mut zip = zip::ZipWriter::new(file);
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated);
    for (name, text) in [
        (TEMPLATE, mission.template()),
        (WAYLINES, mission.waylines()),
    ] {
        zip.start_file(name, options)
            .map_err(std::io::Error::other)?;
        zip.write_all(text.as_bytes())?;
    }
    zip.finish().map_err(std::io::Error::other)?;
    Ok(())
}

/// A sortie's points on the Earth, with what the aircraft does at each.
struct Mission {
    home: Geodetic,
    points: Vec<Point>,
    speed_m_s: f64,
    hover_s: f64,
    takeoff_security_m: f64,
    aircraft: DjiAircraft,
}

/// One placemark: a point of the path, and the photo to take there.
struct Point {
    at: Geodetic,
    /// Metres above the take-off point.
    height_m: f64,
    /// Clockwise from north, degrees within [-180, 180].
    heading_deg: f64,
    /// Degrees, negative looking down (DJI's sign).
    gimbal_pitch_deg: f64,
    inspect: bool,
}

impl Mission {
    fn new(placement: &Placement, sortie: &Sortie, launch: Point3<f64>) -> Self {
        let origin = &placement.origin;
        let home = origin.to_geodetic(&launch);
        // The path starts at home, where the take-off ends.
        let points: Vec<Point> = steps(sortie)
            .into_iter()
            .skip(1)
            .map(|step| {
                let at = origin.to_geodetic(&Point3::from(step.point));
                let heading = origin.heading_deg(step.yaw);
                Point {
                    at,
                    height_m: at.altitude_m - home.altitude_m,
                    heading_deg: if heading > 180.0 {
                        heading - 360.0
                    } else {
                        heading
                    },
                    gimbal_pitch_deg: -step.gimbal_pitch.to_degrees(),
                    inspect: step.waypoint.is_some(),
                }
            })
            .collect();
        let first_climb = points.first().map_or(0.0, |p| p.height_m);
        Self {
            home,
            speed_m_s: placement.speed_m_s,
            hover_s: placement.hover_s,
            takeoff_security_m: first_climb
                .max(placement.min_takeoff_m)
                .clamp(TAKEOFF_SECURITY_M.0, TAKEOFF_SECURITY_M.1),
            points,
            aircraft: placement.dji_aircraft,
        }
    }

    /// `<wpml:missionConfig>`: how to get to the wayline and back, and
    /// for which aircraft.
    fn config(&self) -> String {
        let (drone, sub, payload) = self.aircraft.enums();
        let h = &self.home;
        format!(
            "<wpml:missionConfig>\n\
             <wpml:flyToWaylineMode>safely</wpml:flyToWaylineMode>\n\
             <wpml:finishAction>goHome</wpml:finishAction>\n\
             <wpml:exitOnRCLost>executeLostAction</wpml:exitOnRCLost>\n\
             <wpml:executeRCLostAction>goBack</wpml:executeRCLostAction>\n\
             <wpml:takeOffSecurityHeight>{:.2}</wpml:takeOffSecurityHeight>\n\
             <wpml:takeOffRefPoint>{:.9},{:.9},{:.3}</wpml:takeOffRefPoint>\n\
             <wpml:globalTransitionalSpeed>{}</wpml:globalTransitionalSpeed>\n\
             <wpml:droneInfo><wpml:droneEnumValue>{drone}</wpml:droneEnumValue><wpml:droneSubEnumValue>{sub}</wpml:droneSubEnumValue></wpml:droneInfo>\n\
             <wpml:payloadInfo><wpml:payloadEnumValue>{payload}</wpml:payloadEnumValue><wpml:payloadPositionIndex>0</wpml:payloadPositionIndex></wpml:payloadInfo>\n\
             </wpml:missionConfig>\n",
            self.takeoff_security_m, h.latitude_deg, h.longitude_deg, h.altitude_m, self.speed_m_s,
        )
    }

    /// `wpmz/template.kml`: the waypoint template.
    fn template(&self) -> String {
        let mut placemarks = String::new();
        for (index, p) in self.points.iter().enumerate() {
            let _ = write!(
                placemarks,
                "<Placemark>\n\
                 <Point><coordinates>{}</coordinates></Point>\n\
                 <wpml:index>{index}</wpml:index>\n\
                 <wpml:ellipsoidHeight>{:.3}</wpml:ellipsoidHeight>\n\
                 <wpml:height>{:.3}</wpml:height>\n\
                 <wpml:useGlobalHeight>0</wpml:useGlobalHeight>\n\
                 <wpml:useGlobalSpeed>1</wpml:useGlobalSpeed>\n\
                 <wpml:useGlobalHeadingParam>0</wpml:useGlobalHeadingParam>\n\
                 {}\
                 <wpml:useGlobalTurnParam>1</wpml:useGlobalTurnParam>\n\
                 <wpml:useStraightLine>1</wpml:useStraightLine>\n\
                 <wpml:gimbalPitchAngle>{:.2}</wpml:gimbalPitchAngle>\n\
                 {}</Placemark>\n",
                coordinates(&p.at),
                p.at.altitude_m,
                p.height_m,
                heading_param(p),
                p.gimbal_pitch_deg,
                self.actions(index, p),
            );
        }
        let created = jiff::Timestamp::now().as_millisecond();
        format!(
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
             <kml xmlns=\"http://www.opengis.net/kml/2.2\" xmlns:wpml=\"{NAMESPACE}\">\n<Document>\n\
             <wpml:author>postflight</wpml:author>\n\
             <wpml:createTime>{created}</wpml:createTime>\n\
             <wpml:updateTime>{created}</wpml:updateTime>\n\
             {}\
             <Folder>\n\
             <wpml:templateType>waypoint</wpml:templateType>\n\
             <wpml:templateId>0</wpml:templateId>\n\
             <wpml:waylineCoordinateSysParam><wpml:coordinateMode>WGS84</wpml:coordinateMode><wpml:heightMode>relativeToStartPoint</wpml:heightMode></wpml:waylineCoordinateSysParam>\n\
             <wpml:autoFlightSpeed>{}</wpml:autoFlightSpeed>\n\
             <wpml:globalHeight>{:.3}</wpml:globalHeight>\n\
             <wpml:caliFlightEnable>0</wpml:caliFlightEnable>\n\
             <wpml:gimbalPitchMode>usePointSetting</wpml:gimbalPitchMode>\n\
             <wpml:globalWaypointHeadingParam><wpml:waypointHeadingMode>followWayline</wpml:waypointHeadingMode><wpml:waypointHeadingPathMode>followBadArc</wpml:waypointHeadingPathMode></wpml:globalWaypointHeadingParam>\n\
             <wpml:globalWaypointTurnMode>toPointAndStopWithDiscontinuityCurvature</wpml:globalWaypointTurnMode>\n\
             <wpml:globalUseStraightLine>1</wpml:globalUseStraightLine>\n\
             {placemarks}</Folder>\n</Document>\n</kml>\n",
            self.config(),
            self.speed_m_s,
            self.points.first().map_or(0.0, |p| p.height_m),
        )
    }

    /// `wpmz/waylines.wpml`: the wayline as the aircraft executes it.
    fn waylines(&self) -> String {
        let mut placemarks = String::new();
        for (index, p) in self.points.iter().enumerate() {
            let _ = write!(
                placemarks,
                "<Placemark>\n\
                 <Point><coordinates>{}</coordinates></Point>\n\
                 <wpml:index>{index}</wpml:index>\n\
                 <wpml:executeHeight>{:.3}</wpml:executeHeight>\n\
                 <wpml:waypointSpeed>{}</wpml:waypointSpeed>\n\
                 {}\
                 <wpml:waypointTurnParam><wpml:waypointTurnMode>toPointAndStopWithDiscontinuityCurvature</wpml:waypointTurnMode><wpml:waypointTurnDampingDist>0</wpml:waypointTurnDampingDist></wpml:waypointTurnParam>\n\
                 <wpml:useStraightLine>1</wpml:useStraightLine>\n\
                 {}</Placemark>\n",
                coordinates(&p.at),
                p.height_m,
                self.speed_m_s,
                heading_param(p),
                self.actions(index, p),
            );
        }
        format!(
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
             <kml xmlns=\"http://www.opengis.net/kml/2.2\" xmlns:wpml=\"{NAMESPACE}\">\n<Document>\n\
             {}\
             <Folder>\n\
             <wpml:templateId>0</wpml:templateId>\n\
             <wpml:executeHeightMode>relativeToStartPoint</wpml:executeHeightMode>\n\
             <wpml:waylineId>0</wpml:waylineId>\n\
             <wpml:autoFlightSpeed>{}</wpml:autoFlightSpeed>\n\
             {placemarks}</Folder>\n</Document>\n</kml>\n",
            self.config(),
            self.speed_m_s,
        )
    }

    /// At an inspection waypoint, on arrival: the gimbal to its pitch, a
    /// hover, one photo; elsewhere nothing.
    fn actions(&self, index: usize, p: &Point) -> String {
        if !p.inspect {
            return String::new();
        }
        // Action ids are unique within the mission: three per waypoint.
        let id = 3 * index;
        format!(
            "<wpml:actionGroup>\n\
             <wpml:actionGroupId>{index}</wpml:actionGroupId>\n\
             <wpml:actionGroupStartIndex>{index}</wpml:actionGroupStartIndex>\n\
             <wpml:actionGroupEndIndex>{index}</wpml:actionGroupEndIndex>\n\
             <wpml:actionGroupMode>sequence</wpml:actionGroupMode>\n\
             <wpml:actionTrigger><wpml:actionTriggerType>reachPoint</wpml:actionTriggerType></wpml:actionTrigger>\n\
             <wpml:action><wpml:actionId>{id}</wpml:actionId><wpml:actionActuatorFunc>gimbalRotate</wpml:actionActuatorFunc><wpml:actionActuatorFuncParam>\
             <wpml:gimbalHeadingYawBase>aircraft</wpml:gimbalHeadingYawBase><wpml:gimbalRotateMode>absoluteAngle</wpml:gimbalRotateMode>\
             <wpml:gimbalPitchRotateEnable>1</wpml:gimbalPitchRotateEnable><wpml:gimbalPitchRotateAngle>{:.2}</wpml:gimbalPitchRotateAngle>\
             <wpml:gimbalRollRotateEnable>0</wpml:gimbalRollRotateEnable><wpml:gimbalRollRotateAngle>0</wpml:gimbalRollRotateAngle>\
             <wpml:gimbalYawRotateEnable>0</wpml:gimbalYawRotateEnable><wpml:gimbalYawRotateAngle>0</wpml:gimbalYawRotateAngle>\
             <wpml:gimbalRotateTimeEnable>0</wpml:gimbalRotateTimeEnable><wpml:gimbalRotateTime>0</wpml:gimbalRotateTime>\
             <wpml:payloadPositionIndex>0</wpml:payloadPositionIndex></wpml:actionActuatorFuncParam></wpml:action>\n\
             <wpml:action><wpml:actionId>{}</wpml:actionId><wpml:actionActuatorFunc>hover</wpml:actionActuatorFunc><wpml:actionActuatorFuncParam><wpml:hoverTime>{}</wpml:hoverTime></wpml:actionActuatorFuncParam></wpml:action>\n\
             <wpml:action><wpml:actionId>{}</wpml:actionId><wpml:actionActuatorFunc>takePhoto</wpml:actionActuatorFunc><wpml:actionActuatorFuncParam><wpml:fileSuffix>postflight-{}</wpml:fileSuffix><wpml:payloadPositionIndex>0</wpml:payloadPositionIndex><wpml:useGlobalPayloadLensIndex>1</wpml:useGlobalPayloadLensIndex></wpml:actionActuatorFuncParam></wpml:action>\n\
             </wpml:actionGroup>\n",
            p.gimbal_pitch_deg,
            id + 1,
            self.hover_s,
            id + 2,
            index,
        )
    }
}

/// The waypoint's own heading, turned to smoothly on the way there.
fn heading_param(p: &Point) -> String {
    format!(
        "<wpml:waypointHeadingParam><wpml:waypointHeadingMode>smoothTransition</wpml:waypointHeadingMode><wpml:waypointHeadingAngle>{:.2}</wpml:waypointHeadingAngle><wpml:waypointPoiPoint>0.000000,0.000000,0.000000</wpml:waypointPoiPoint><wpml:waypointHeadingAngleEnable>1</wpml:waypointHeadingAngleEnable><wpml:waypointHeadingPathMode>followBadArc</wpml:waypointHeadingPathMode></wpml:waypointHeadingParam>\n",
        p.heading_deg
    )
}

/// KML's `longitude,latitude`.
fn coordinates(g: &Geodetic) -> String {
    format!("{:.9},{:.9}", g.longitude_deg, g.latitude_deg)
}
