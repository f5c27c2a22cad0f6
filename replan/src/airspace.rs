//! Where the follow-up may not fly: keep-out zones (vertical prisms, given
//! in the map frame in the settings or on the Earth as GeoJSON placed by
//! the geo origin) and a ceiling above the take-off point. Every viewpoint
//! and every path point of the follow-up is outside the zones and below
//! the ceiling ([`crate::free_space::FreeSpace`] asks [`Airspace`]).
//!
//! A GeoJSON zone is a `Polygon` or `MultiPolygon` feature (RFC 7946:
//! longitude, latitude), its altitude band in the properties as EUROCAE
//! ED-269 geographical zones give it: `lowerLimit` and `upperLimit` in
//! `uomDimensions` (`M`, the default, or `FT`), each above the WGS 84
//! ellipsoid (`WGS84`, as GPS altitudes and the geo origin's are) or above
//! the take-off point (`AGL`, as the missions' relative altitudes are).
//! `AMSL` is refused: postflight has no geoid model to turn it into either.

use std::path::Path;

use geojson::{Feature, GeoJson, GeometryValue, JsonValue};
use nalgebra::Point3;
use postflight_core::geo::{GeoOrigin, Geodetic};
use postflight_core::region::Region;

use crate::error::ReplanError;
use crate::settings::{ReplanConfig, keys};

/// The keep-out zones and the ceiling, in the map frame.
#[derive(Debug, Clone, Default)]
pub struct Airspace {
    zones: Vec<Region>,
    /// Each zone's bounding box, `[min, max]`, as a quick first test.
    bounds: Vec<[Point3<f64>; 2]>,
    /// Highest z a point may have (map frame), if any.
    ceiling_z: Option<f64>,
}

impl Airspace {
    pub fn new(zones: Vec<Region>, ceiling_z: Option<f64>) -> Self {
        let bounds = zones.iter().map(bounds).collect();
        Self {
            zones,
            bounds,
            ceiling_z,
        }
    }

    pub fn zones(&self) -> &[Region] {
        &self.zones
    }

    pub fn ceiling_z(&self) -> Option<f64> {
        self.ceiling_z
    }

    /// The zone holding `p`, if one does.
    pub fn zone_at(&self, p: &Point3<f64>) -> Option<&Region> {
        self.zones
            .iter()
            .zip(&self.bounds)
            .find(|(z, b)| overlaps(b, p, p) && z.contains(p))
            .map(|(z, _)| z)
    }

    /// Whether the vehicle may be at `p`.
    pub fn allows(&self, p: &Point3<f64>) -> bool {
        self.ceiling_z.is_none_or(|c| p.z <= c) && self.zone_at(p).is_none()
    }

    /// Whether the vehicle may fly straight from `a` to `b`: below the
    /// ceiling at both ends (so all along) and through no zone.
    pub fn allows_segment(&self, a: &Point3<f64>, b: &Point3<f64>) -> bool {
        self.ceiling_z.is_none_or(|c| a.z <= c && b.z <= c)
            && !self
                .zones
                .iter()
                .zip(&self.bounds)
                .any(|(z, b_)| overlaps(b_, a, b) && z.meets_segment(a, b))
    }

    /// Whether every point within `margin` of `p` (a box) is further than
    /// that from every zone's bounding box and below the ceiling: a quick
    /// test that spares the exact ones.
    pub fn clear_around(&self, p: &Point3<f64>, margin: f64) -> bool {
        self.ceiling_z.is_none_or(|c| p.z + margin <= c)
            && self
                .bounds
                .iter()
                .all(|[lo, hi]| (0..3).any(|k| p[k] + margin < lo[k] || p[k] - margin > hi[k]))
    }
}

/// Whether the box `[lo, hi]` meets the box spanned by `a` and `b`.
fn overlaps([lo, hi]: &[Point3<f64>; 2], a: &Point3<f64>, b: &Point3<f64>) -> bool {
    (0..3).all(|k| a[k].max(b[k]) >= lo[k] && a[k].min(b[k]) <= hi[k])
}

fn bounds(zone: &Region) -> [Point3<f64>; 2] {
    let (mut lo, mut hi) = (
        Point3::new(
            f64::INFINITY,
            f64::INFINITY,
            zone.bottom_m.unwrap_or(f64::NEG_INFINITY),
        ),
        Point3::new(
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
            zone.top_m.unwrap_or(f64::INFINITY),
        ),
    );
    for [x, y] in &zone.outline {
        (lo.x, lo.y) = (lo.x.min(*x), lo.y.min(*y));
        (hi.x, hi.y) = (hi.x.max(*x), hi.y.max(*y));
    }
    [lo, hi]
}

/// Keep-out zones from a GeoJSON file, in the map frame of `origin`;
/// `take_off` is the point `AGL` heights are above. The error says what is
/// wrong with the file, for the caller to name it.
pub fn read_zones(
    path: &Path,
    origin: &GeoOrigin,
    take_off: &Point3<f64>,
) -> Result<Vec<Region>, String> {
    let text = postflight_core::user_file::read_to_string(path).map_err(|e| e.to_string())?;
    let features = match text.parse::<GeoJson>().map_err(|e| e.to_string())? {
        GeoJson::FeatureCollection(c) => c.features,
        GeoJson::Feature(f) => vec![f],
        GeoJson::Geometry(_) => return Err("it is a bare geometry, not features".into()),
    };
    let take_off_altitude = origin.to_geodetic(take_off).altitude_m;
    let mut zones = Vec::new();
    for (k, feature) in features.iter().enumerate() {
        let name = match feature.property("name").and_then(JsonValue::as_str) {
            Some(n) => n.to_string(),
            None => format!("feature {}", k + 1),
        };
        let polygons = match feature.geometry.as_ref().map(|g| &g.value) {
            Some(GeometryValue::Polygon { coordinates }) => vec![coordinates.clone()],
            Some(GeometryValue::MultiPolygon { coordinates }) => coordinates.clone(),
            other => {
                let kind = other.map_or("no geometry", GeometryValue::type_name);
                return Err(format!("{name} is a {kind}, not a Polygon or MultiPolygon"));
            }
        };
        let heights = Heights::of(feature).map_err(|why| format!("{name}: {why}"))?;
        for (p, rings) in polygons.iter().enumerate() {
            // The outer ring: a hole (a further ring) is kept out with it.
            let Some(ring) = rings.first() else { continue };
            let corners: Vec<Point3<f64>> = ring
                .iter()
                .map(|position| match position.as_slice() {
                    [lon, lat, ..] => {
                        let at = Geodetic {
                            latitude_deg: *lat,
                            longitude_deg: *lon,
                            altitude_m: take_off_altitude,
                        };
                        // GeoJSON's order is longitude, latitude (RFC 7946).
                        at.check().map_err(|e| {
                            format!("{name}: position [{lon}, {lat}]: {e}; GeoJSON gives longitude first")
                        })?;
                        Ok(origin.to_local(&at))
                    }
                    _ => Err(format!("{name} has a position without two numbers")),
                })
                .collect::<Result<_, _>>()?;
            let mut outline: Vec<[f64; 2]> = corners.iter().map(|c| [c.x, c.y]).collect();
            // GeoJSON rings repeat their first corner at the end.
            if outline.len() > 1 && outline.first() == outline.last() {
                outline.pop();
            }
            let level = |h: Option<Height>| {
                h.map(|h| match h {
                    Height::Ellipsoid(alt) => alt - take_off_altitude + take_off.z,
                    Height::AboveTakeOff(m) => m + take_off.z,
                })
            };
            zones.push(Region {
                name: if polygons.len() > 1 {
                    format!("{name} ({})", p + 1)
                } else {
                    name.clone()
                },
                outline,
                bottom_m: level(heights.lower),
                top_m: level(heights.upper),
            });
        }
    }
    Ok(zones)
}

/// A height of a zone's band.
#[derive(Clone, Copy)]
enum Height {
    /// Metres above the WGS 84 ellipsoid.
    Ellipsoid(f64),
    /// Metres above the take-off point.
    AboveTakeOff(f64),
}

/// A feature's altitude band (ED-269's properties).
struct Heights {
    lower: Option<Height>,
    upper: Option<Height>,
}

impl Heights {
    fn of(feature: &Feature) -> Result<Self, String> {
        let metres_per_unit = match feature
            .property("uomDimensions")
            .and_then(JsonValue::as_str)
        {
            None | Some("M") => 1.0,
            Some("FT") => 0.3048,
            Some(other) => return Err(format!("uomDimensions is {other}, not M or FT")),
        };
        let height = |limit: &str, reference: &str| -> Result<Option<Height>, String> {
            let Some(value) = feature.property(limit).filter(|v| !v.is_null()) else {
                return Ok(None);
            };
            let metres = value
                .as_f64()
                .filter(|v| v.is_finite())
                .ok_or(format!("{limit} is {value}, not a number"))?
                * metres_per_unit;
            match feature.property(reference).and_then(JsonValue::as_str) {
                None | Some("WGS84") => Ok(Some(Height::Ellipsoid(metres))),
                Some("AGL") => Ok(Some(Height::AboveTakeOff(metres))),
                Some("AMSL") => Err(format!(
                    "{reference} is AMSL, which needs a geoid model; give {limit} above the WGS 84 ellipsoid (WGS84) or above the take-off point (AGL)"
                )),
                Some(other) => Err(format!("{reference} is {other}, not WGS84 or AGL")),
            }
        };
        Ok(Self {
            lower: height("lowerLimit", "lowerVerticalReference")?,
            upper: height("upperLimit", "upperVerticalReference")?,
        })
    }
}

/// The keep-out zones of the settings and the zones file (placed by the
/// geo origin), and the ceiling above the take-off point; refused when a
/// zone cannot be used or holds the take-off point.
pub(crate) fn airspace(
    s: &ReplanConfig,
    origin: Option<&GeoOrigin>,
    launch: Point3<f64>,
) -> Result<Airspace, ReplanError> {
    let mut zones = Vec::new();
    for zone in &s.keep_out {
        zone.check(keys::keep_out)?;
        zones.push(zone.clone());
    }
    if let Some(path) = &s.keep_out_file {
        let origin =
            origin.ok_or_else(|| ReplanError::KeepOutWithoutGeoOrigin { path: path.clone() })?;
        let from_file =
            read_zones(path, origin, &launch).map_err(|why| ReplanError::KeepOutFile {
                path: path.clone(),
                why,
            })?;
        for zone in from_file {
            zone.check(keys::keep_out_file)?;
            zones.push(zone);
        }
    }
    let airspace = Airspace::new(zones, s.ceiling_m.map(|c| launch.z + c));
    if let Some(zone) = airspace.zone_at(&launch) {
        return Err(ReplanError::HomeInKeepOut {
            home: launch.coords.into(),
            zone: zone.name.clone(),
        });
    }
    Ok(airspace)
}

/// What the ground station's geofence cannot hold: a zone with heights
/// (fences are polygons at every altitude; writing it as one would bar the
/// flight from passing over or under it), and the ceiling (the vehicle's
/// own setting, PX4's `GF_MAX_VER_DIST` or ArduPilot's `FENCE_ALT_MAX`).
pub(crate) fn unfenced(airspace: &Airspace) -> Vec<String> {
    let mut warnings: Vec<String> = airspace
        .zones()
        .iter()
        .filter(|z| !z.is_column())
        .map(|z| {
            format!(
                "keep-out zone '{}' has an altitude band, which a QGroundControl geofence (polygons at every altitude) cannot hold: the plan keeps out of it, the missions' geofence does not",
                z.name
            )
        })
        .collect();
    if let Some(z) = airspace.ceiling_z() {
        warnings.push(format!(
            "the ceiling (map z {z:.1} m) is kept by the plan; set it on the vehicle too (PX4 GF_MAX_VER_DIST, ArduPilot FENCE_ALT_MAX): a QGroundControl plan file cannot hold it"
        ));
    }
    warnings
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(bottom_m: Option<f64>, top_m: Option<f64>) -> Region {
        Region {
            name: "square".into(),
            outline: vec![[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]],
            bottom_m,
            top_m,
        }
    }

    #[test]
    fn zones_and_the_ceiling_bar_points_and_segments() {
        let air = Airspace::new(vec![square(Some(1.0), Some(3.0))], Some(10.0));
        let p = |x, y, z| Point3::new(x, y, z);
        assert!(!air.allows(&p(1.0, 1.0, 2.0)));
        assert!(air.allows(&p(1.0, 1.0, 4.0)));
        assert!(!air.allows(&p(5.0, 5.0, 10.5)), "above the ceiling");
        assert!(!air.allows_segment(&p(-1.0, 1.0, 2.0), &p(3.0, 1.0, 2.0)));
        assert!(air.allows_segment(&p(-1.0, 1.0, 4.0), &p(3.0, 1.0, 4.0)));
        assert!(!air.allows_segment(&p(-1.0, 5.0, 4.0), &p(3.0, 5.0, 11.0)));
        assert!(air.clear_around(&p(-2.0, 1.0, 2.0), 0.5));
        assert!(!air.clear_around(&p(-0.4, 1.0, 2.0), 0.5));
        assert!(
            !air.clear_around(&p(-5.0, 1.0, 9.8), 0.5),
            "near the ceiling"
        );
        // Nothing barred by default.
        let open = Airspace::default();
        assert!(
            open.allows(&p(1.0, 1.0, 2.0))
                && open.allows_segment(&p(-1.0, 1.0, 2.0), &p(3.0, 1.0, 99.0))
        );
    }

    #[test]
    fn geojson_zones_are_placed_by_the_geo_origin() {
        let origin: GeoOrigin = "47.4,8.5,400,30".parse().unwrap();
        let take_off = Point3::new(1.0, 2.0, -3.0);
        // Corners 10 m east and north of the origin, in the map frame.
        let corners: Vec<Point3<f64>> = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]]
            .iter()
            .map(|[x, y]| Point3::new(*x, *y, 0.0))
            .collect();
        let ring: Vec<[f64; 2]> = corners
            .iter()
            .chain(corners.first())
            .map(|c| {
                let g = origin.to_geodetic(c);
                [g.longitude_deg, g.latitude_deg]
            })
            .collect();
        let text = serde_json::json!({
            "type": "FeatureCollection",
            "features": [{
                "type": "Feature",
                "properties": {
                    "name": "carriageway",
                    "lowerLimit": 13.0, "lowerVerticalReference": "AGL",
                    "upperLimit": 1312.3359580052494, "upperVerticalReference": "WGS84",
                    "uomDimensions": "FT"
                },
                "geometry": {"type": "Polygon", "coordinates": [ring]}
            }]
        });
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("zones.geojson");
        std::fs::write(&path, text.to_string()).unwrap();
        let zones = read_zones(&path, &origin, &take_off).unwrap();
        assert_eq!(zones.len(), 1);
        let zone = &zones[0];
        assert_eq!(zone.name, "carriageway");
        assert_eq!(zone.outline.len(), 4);
        for (got, want) in zone.outline.iter().zip(&corners) {
            assert!((got[0] - want.x).abs() < 1e-3 && (got[1] - want.y).abs() < 1e-3);
        }
        // 13 ft above the take-off point; 400 m above the ellipsoid is the
        // origin's own altitude (map z 0, within the Earth's curvature).
        assert!((zone.bottom_m.unwrap() - (-3.0 + 13.0 * 0.3048)).abs() < 1e-6);
        assert!(zone.top_m.unwrap().abs() < 0.01, "{:?}", zone.top_m);

        let amsl = text.to_string().replace("\"WGS84\"", "\"AMSL\"");
        std::fs::write(&path, amsl).unwrap();
        let why = read_zones(&path, &origin, &take_off).unwrap_err();
        assert!(
            why.contains("carriageway: upperVerticalReference is AMSL"),
            "{why}"
        );
        std::fs::write(&path, r#"{"type": "Point", "coordinates": [8.5, 47.4]}"#).unwrap();
        assert!(
            read_zones(&path, &origin, &take_off)
                .unwrap_err()
                .contains("bare geometry")
        );
    }

    #[test]
    fn a_position_off_the_earth_is_refused_with_the_order_named() {
        // Latitude first, as people write it: 200 is no latitude.
        let text = r#"{"type": "Feature", "properties": {"name": "bridge"},
            "geometry": {"type": "Polygon", "coordinates": [[[47.4, 8.5], [47.4, 200], [47.5, 8.5], [47.4, 8.5]]]}}"#;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("zones.geojson");
        std::fs::write(&path, text).unwrap();
        let origin: GeoOrigin = "47.4,8.5,400,0".parse().unwrap();
        let err = read_zones(&path, &origin, &Point3::origin()).unwrap_err();
        assert!(
            err.contains("bridge: position [47.4, 200]") && err.contains("longitude first"),
            "{err}"
        );
    }
}
