//! Where the map frame is on the Earth: a geo origin (the WGS 84 position of
//! the map's origin and the heading of its x axis), the conversions between
//! map coordinates and latitude, longitude and altitude, and the origin
//! found by aligning a flight's GPS fixes to its trajectory.
//!
//! The map frame is taken as a local tangent frame (ROS REP 103: z up) at
//! the origin, turned by `yaw_deg` about z: east-north-up coordinates are
//! the map's rotated by the yaw. Positions go through Earth-centred
//! coordinates on the WGS 84 ellipsoid, exact at any distance.

use map_3d::Ellipsoid;
use nalgebra::{Point3, Rotation3, Vector3};
use serde::{Deserialize, Serialize};

use crate::shown::Shown;

/// A position on the Earth.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Geodetic {
    /// WGS 84 latitude and longitude, degrees.
    pub latitude_deg: f64,
    pub longitude_deg: f64,
    /// Altitude, metres, in the datum given (above the ellipsoid for GPS).
    pub altitude_m: f64,
}

impl Geodetic {
    /// Altitudes further from the ellipsoid than this, metres, are no
    /// flight's (the deepest mine, the highest drone are some km).
    pub const MAX_ALTITUDE_M: f64 = 100_000.0;

    /// Latitude within ±90°, longitude within ±180°, altitude within
    /// ±[`Self::MAX_ALTITUDE_M`], every value finite.
    pub fn check(&self) -> Result<(), String> {
        let Self {
            latitude_deg: lat,
            longitude_deg: lon,
            altitude_m: alt,
        } = *self;
        if !((-90.0..=90.0).contains(&lat) && (-180.0..=180.0).contains(&lon)) {
            return Err(format!(
                "{},{} is not a latitude and longitude in degrees (latitude within ±90, longitude within ±180)",
                Shown(lat),
                Shown(lon)
            ));
        }
        if !(-Self::MAX_ALTITUDE_M..=Self::MAX_ALTITUDE_M).contains(&alt) {
            return Err(format!(
                "altitude {} m is not a flight's (within ±{} m)",
                Shown(alt),
                Self::MAX_ALTITUDE_M
            ));
        }
        Ok(())
    }
}

/// The map frame's origin on the Earth and the heading of its x axis.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GeoOrigin {
    #[serde(flatten)]
    pub position: Geodetic,
    /// Angle from east to the map's x axis, counter-clockwise, degrees
    /// (0: the map is east-north-up).
    pub yaw_deg: f64,
}

impl std::str::FromStr for GeoOrigin {
    type Err = String;

    /// As [`GeoOrigin::parse`] reads it.
    fn from_str(text: &str) -> Result<Self, String> {
        Self::parse(text)
    }
}

/// A geo origin as `postflight.toml` gives it: `[LAT, LON, ALT]` or `[LAT,
/// LON, ALT, YAW_DEG]`, checked as it is read (`#[serde(with)]` for an
/// `Option<GeoOrigin>`).
pub mod geo_origin_values {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    use super::GeoOrigin;

    pub fn serialize<S: Serializer>(origin: &Option<GeoOrigin>, s: S) -> Result<S::Ok, S::Error> {
        origin
            .map(|o| {
                let p = o.position;
                [p.latitude_deg, p.longitude_deg, p.altitude_m, o.yaw_deg]
            })
            .serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<GeoOrigin>, D::Error> {
        Option::<Vec<f64>>::deserialize(d)?
            .map(|values| {
                GeoOrigin::from_values(&values).map_err(|why| {
                    serde::de::Error::custom(format!(
                        "geo_origin must be [LAT, LON, ALT] or [LAT, LON, ALT, YAW_DEG] ({why})"
                    ))
                })
            })
            .transpose()
    }
}

impl GeoOrigin {
    /// `LAT,LON,ALT[,YAW_DEG]`: degrees, metres, and the yaw of the map's
    /// x axis from east (default 0).
    pub fn parse(text: &str) -> Result<Self, String> {
        let values = crate::setting::comma_numbers(text).ok_or_else(|| {
            format!("expected LAT,LON,ALT[,YAW_DEG] in degrees and metres, not '{text}'")
        })?;
        Self::from_values(&values)
    }

    /// `[LAT, LON, ALT]` or `[LAT, LON, ALT, YAW_DEG]`.
    pub fn from_values(values: &[f64]) -> Result<Self, String> {
        let (latitude_deg, longitude_deg, altitude_m, yaw_deg) = match *values {
            [lat, lon, alt] => (lat, lon, alt, 0.0),
            [lat, lon, alt, yaw] => (lat, lon, alt, yaw),
            _ => {
                return Err(format!(
                    "expected LAT,LON,ALT[,YAW_DEG], got {} numbers",
                    values.len()
                ));
            }
        };
        let origin = Self {
            position: Geodetic {
                latitude_deg,
                longitude_deg,
                altitude_m,
            },
            yaw_deg,
        };
        origin.check()?;
        Ok(origin)
    }

    /// Its position passes [`Geodetic::check`], its yaw is finite.
    pub fn check(&self) -> Result<(), String> {
        self.position.check()?;
        if !self.yaw_deg.is_finite() {
            return Err(format!(
                "yaw {} is not an angle in degrees",
                Shown(self.yaw_deg)
            ));
        }
        Ok(())
    }

    /// The map point's position on the Earth.
    pub fn to_geodetic(&self, local: &Point3<f64>) -> Geodetic {
        let enu = self.map_to_enu() * local.coords;
        let o = &self.position;
        let (lat, lon, alt) = map_3d::enu2geodetic(
            enu.x,
            enu.y,
            enu.z,
            o.latitude_deg.to_radians(),
            o.longitude_deg.to_radians(),
            o.altitude_m,
            Ellipsoid::WGS84,
        );
        Geodetic {
            latitude_deg: lat.to_degrees(),
            longitude_deg: lon.to_degrees(),
            altitude_m: alt,
        }
    }

    /// A position on the Earth in map coordinates.
    pub fn to_local(&self, g: &Geodetic) -> Point3<f64> {
        let o = &self.position;
        let (e, n, u) = map_3d::geodetic2enu(
            g.latitude_deg.to_radians(),
            g.longitude_deg.to_radians(),
            g.altitude_m,
            o.latitude_deg.to_radians(),
            o.longitude_deg.to_radians(),
            o.altitude_m,
            Ellipsoid::WGS84,
        );
        Point3::from(self.map_to_enu().inverse() * Vector3::new(e, n, u))
    }

    /// Compass heading (clockwise from north, degrees in `[0, 360)`) of a
    /// map-frame yaw (counter-clockwise from the map's x, radians).
    pub fn heading_deg(&self, yaw: f64) -> f64 {
        (90.0 - yaw.to_degrees() - self.yaw_deg).rem_euclid(360.0)
    }

    fn map_to_enu(&self) -> Rotation3<f64> {
        Rotation3::from_axis_angle(&Vector3::z_axis(), self.yaw_deg.to_radians())
    }
}

/// A geo origin found from GPS fixes, and how well they agree with it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GeoAlignment {
    pub origin: GeoOrigin,
    /// Fixes aligned (each with a trajectory pose at its time).
    pub fixes: usize,
    /// Root mean square distance between the fixes and the trajectory
    /// placed by the origin, metres.
    pub rms_m: f64,
    /// Largest horizontal distance of a fix from their centre, metres
    /// (the yaw is as good as the fixes' noise over this).
    pub spread_m: f64,
}

impl GeoAlignment {
    /// Fewer fixes leave the alignment to chance.
    pub const MIN_FIXES: usize = 5;
    /// Fixes closer together than this cannot tell the map's heading.
    pub const MIN_SPREAD_M: f64 = 10.0;

    /// The origin and yaw placing the trajectory positions `local` onto
    /// the fixes `fixes` (the same length, in pairs): a rigid motion about
    /// the vertical, least squares.
    pub fn fit(local: &[Point3<f64>], fixes: &[Geodetic]) -> Result<Self, String> {
        if local.len() != fixes.len() || fixes.len() < Self::MIN_FIXES {
            return Err(format!(
                "{} GPS fixes with a pose at their time; aligning needs {} or more",
                fixes.len().min(local.len()),
                Self::MIN_FIXES
            ));
        }
        let mut reference = GeoOrigin {
            position: fixes[0],
            yaw_deg: 0.0,
        };
        // The tangent frame of the first fix is not the origin's; a second
        // fit in the origin's own frame removes the difference.
        let mut fit = fit_in(&reference, local, fixes)?;
        reference = fit.origin;
        reference.yaw_deg = 0.0;
        fit = fit_in(&reference, local, fixes)?;
        Ok(fit)
    }
}

fn fit_in(
    reference: &GeoOrigin,
    local: &[Point3<f64>],
    fixes: &[Geodetic],
) -> Result<GeoAlignment, String> {
    let enu: Vec<Vector3<f64>> = fixes.iter().map(|g| reference.to_local(g).coords).collect();
    let n = local.len() as f64;
    let local_mean = local.iter().map(|p| p.coords).sum::<Vector3<f64>>() / n;
    let enu_mean = enu.iter().sum::<Vector3<f64>>() / n;
    let spread_m = enu
        .iter()
        .map(|e| (e - enu_mean).xy().norm())
        .fold(0.0, f64::max);
    if spread_m < GeoAlignment::MIN_SPREAD_M {
        return Err(format!(
            "the GPS fixes lie within {spread_m:.1} m of each other, too close to tell the map's heading (needs {} m)",
            GeoAlignment::MIN_SPREAD_M
        ));
    }
    let (mut sin, mut cos) = (0.0, 0.0);
    for (p, e) in local.iter().zip(&enu) {
        let (p, e) = (p.coords - local_mean, e - enu_mean);
        sin += p.x * e.y - p.y * e.x;
        cos += p.x * e.x + p.y * e.y;
    }
    let yaw = f64::atan2(sin, cos);
    let rotation = Rotation3::from_axis_angle(&Vector3::z_axis(), yaw);
    let shift = enu_mean - rotation * local_mean;
    let squared: f64 = local
        .iter()
        .zip(&enu)
        .map(|(p, e)| (rotation * p.coords + shift - e).norm_squared())
        .sum();
    Ok(GeoAlignment {
        origin: GeoOrigin {
            position: reference.to_geodetic(&Point3::from(shift)),
            yaw_deg: yaw.to_degrees(),
        },
        fixes: local.len(),
        rms_m: (squared / n).sqrt(),
        spread_m,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_origin_parses_with_or_without_a_yaw_and_rejects_what_is_not_one() {
        let o = GeoOrigin::parse("47.397742, 8.545594, 488.0").unwrap();
        assert_eq!((o.position.latitude_deg, o.yaw_deg), (47.397742, 0.0));
        assert_eq!(GeoOrigin::parse("1,2,3,90").unwrap().yaw_deg, 90.0);
        for bad in ["1,2", "1,2,3,4,5", "91,0,0", "0,181,0", "a,b,c", "0,0,inf"] {
            assert!(GeoOrigin::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn headings_turn_with_the_map() {
        let east_north_up = GeoOrigin::parse("0,0,0").unwrap();
        assert_eq!(east_north_up.heading_deg(0.0), 90.0);
        assert_eq!(east_north_up.heading_deg(std::f64::consts::FRAC_PI_2), 0.0);
        let turned = GeoOrigin::parse("0,0,0,90").unwrap();
        assert_eq!(turned.heading_deg(0.0), 0.0);
        // The map's x axis points north: a point 100 m along x is north.
        let g = turned.to_geodetic(&Point3::new(100.0, 0.0, 0.0));
        assert!(g.latitude_deg > 0.0 && g.longitude_deg.abs() < 1e-12);
    }

    #[test]
    fn fixes_of_a_turned_trajectory_give_back_its_origin_and_yaw() {
        let truth = GeoOrigin::parse("38.6916,-9.1770,80.0,30.0").unwrap();
        let local: Vec<Point3<f64>> = (0..40)
            .map(|i| {
                let t = f64::from(i) * 0.3;
                Point3::new(60.0 * t.cos(), 25.0 * t.sin(), 10.0 + t)
            })
            .collect();
        let fixes: Vec<Geodetic> = local.iter().map(|p| truth.to_geodetic(p)).collect();
        let fit = GeoAlignment::fit(&local, &fixes).unwrap();
        assert!(fit.rms_m < 1e-6, "{fit:?}");
        assert!((fit.origin.yaw_deg - 30.0).abs() < 1e-6, "{fit:?}");
        let back = fit.origin.to_geodetic(&Point3::origin());
        assert!(truth.to_local(&back).coords.norm() < 1e-4, "{fit:?}");
        let near: Vec<_> = local
            .iter()
            .map(|p| Point3::new(p.x * 0.01, p.y * 0.01, p.z))
            .collect();
        let near_fixes: Vec<_> = near.iter().map(|p| truth.to_geodetic(p)).collect();
        assert!(
            GeoAlignment::fit(&near, &near_fixes)
                .unwrap_err()
                .contains("too close")
        );
    }
}
