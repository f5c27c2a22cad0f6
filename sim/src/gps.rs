//! GPS fixes of the simulated flight: the body's true position placed on
//! the Earth by a geo origin (the world frame's), with white noise, at
//! [`RATE_HZ`], written to the recording of the sortie flying at the time
//! as `sensor_msgs/NavSatFix`. GPS is on the Earth, not in a SLAM frame:
//! each sortie's fixes say where its frame is (ingest fits them to its
//! poses).

use nalgebra::{Point3, Vector3};
use postflight_core::geo::GeoOrigin;
use serde::Serialize;

use crate::SimError;
use crate::record::{self, header};
use crate::rng::Rng;
use crate::sortie::Sorties;
use ingest::ros::msg;

/// Fixes per second, as consumer receivers give them.
pub const RATE_HZ: f64 = 5.0;
/// The fixes' noise, 1 sigma, metres: horizontal and vertical, as an
/// SBAS-aided receiver in open sky gives (white here: a real receiver's
/// errors drift slowly, which averages out less).
pub const SIGMA_M: (f64, f64) = (0.3, 0.5);

/// What truth.json says of the GPS.
#[derive(Debug, Clone, Serialize)]
pub struct GpsTruth {
    /// The world frame on the Earth.
    pub origin: GeoOrigin,
    pub rate_hz: f64,
    pub horizontal_sigma_m: f64,
    pub vertical_sigma_m: f64,
}

impl GpsTruth {
    pub fn new(origin: GeoOrigin) -> Self {
        Self {
            origin,
            rate_hz: RATE_HZ,
            horizontal_sigma_m: SIGMA_M.0,
            vertical_sigma_m: SIGMA_M.1,
        }
    }
}

/// Writes the fixes in time order, as the poses and frames are.
pub struct GpsWriter {
    origin: GeoOrigin,
    next: usize,
    noise: Rng,
}

impl GpsWriter {
    pub fn new(origin: GeoOrigin, seed: u64) -> Self {
        Self {
            origin,
            next: 0,
            noise: Rng::stream(seed, "gps noise"),
        }
    }

    /// Write the fixes stamped up to `t` (of a flight `duration_s` long)
    /// not yet written; `position(t)` is the body's true world position.
    pub fn write_until(
        &mut self,
        t: f64,
        duration_s: f64,
        position: impl Fn(f64) -> Point3<f64>,
        sorties: &mut Sorties,
    ) -> Result<(), SimError> {
        loop {
            let ft = self.next as f64 / RATE_HZ;
            if ft > t.min(duration_s) {
                return Ok(());
            }
            let (h, v) = SIGMA_M;
            let noise = Vector3::new(
                self.noise.normal() * h,
                self.noise.normal() * h,
                self.noise.normal() * v,
            );
            let g = self.origin.to_geodetic(&(position(ft) + noise));
            let (rec, _, stamp) = sorties.at(ft);
            let fix = msg::NavSatFix {
                header: header(stamp, "gps"),
                status: msg::NavSatStatus {
                    status: 0,
                    service: 1,
                },
                latitude: g.latitude_deg,
                longitude: g.longitude_deg,
                altitude: g.altitude_m,
                position_covariance: [[h * h, 0.0, 0.0], [0.0, h * h, 0.0], [0.0, 0.0, v * v]],
                // COVARIANCE_TYPE_DIAGONAL_KNOWN.
                position_covariance_type: 2,
            };
            rec.write(record::GPS_TOPIC, stamp + 2_000_000, &fix)?;
            self.next += 1;
        }
    }
}
