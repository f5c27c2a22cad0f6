//! Where a flight's frames looked: each usable frame judged by coverage's
//! View model rules (distance band, image, incidence, occlusion, GSD,
//! blur), all but the viewing cone. The cone says which part of an image
//! counts towards coverage; the detector reads the whole image, so a crack
//! that ran on at an image's edge would have been found there.

use nalgebra::{Point3, Vector3};
use postflight_core::map::{FaceSide, SlamMap};
use postflight_core::{Flight, Intrinsics, ViewModel};

use coverage::cover::judge;
use coverage::{CoverageError, Face, Shot};

/// A flight's frames, to ask which of them had a surface point in view.
pub struct FramesInView {
    shots: Vec<Shot>,
    lenses: Vec<Intrinsics>,
    map: SlamMap,
    view: ViewModel,
}

impl FramesInView {
    /// `flight`'s posed frames against its `map`, under `view` (its
    /// coverage's) opened to the whole image. Frames without a recorded
    /// exposure count as sharp: their blur is not known.
    pub fn new(flight: &Flight, map: SlamMap, view: &ViewModel) -> Result<Self, CoverageError> {
        let lenses = coverage::lenses(flight)?;
        let shots = coverage::flight_shots(flight, &lenses, &map, None).shots;
        Ok(Self::of_shots(shots, lenses, map, view))
    }

    /// `shots` (through `lenses`) against `map`, under `view` opened to
    /// the whole image.
    pub fn of_shots(
        shots: Vec<Shot>,
        lenses: Vec<Intrinsics>,
        map: SlamMap,
        view: &ViewModel,
    ) -> Self {
        Self {
            shots,
            lenses,
            map,
            view: ViewModel {
                cone_apex_deg: 180.0,
                ..*view
            },
        }
    }

    /// The finest GSD, millimetres per pixel, of the frames that had the
    /// surface point (outward `normal`) in view; `None` where none did.
    pub fn finest_gsd_mm(&self, point: &Point3<f64>, normal: &Vector3<f64>) -> Option<f64> {
        let side = FaceSide::nearest(normal);
        let face = Face {
            voxel: self.map.voxels.grid.voxel_of(&(point - normal * 1e-3)),
            side,
            centre: *point,
            normal: *normal,
        };
        self.shots
            .iter()
            .filter_map(|shot| judge(&face, shot, &self.lenses, &self.map, &self.view).ok())
            .map(|sight| sight.gsd_mm)
            .min_by(f64::total_cmp)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Matrix3, Translation3, UnitQuaternion};
    use postflight_core::map::{PointCloud, VoxelGrid};

    /// A wall in the plane x = 0.45 facing +x, and a camera 3.5 m out
    /// looking back at it (640 x 480 px, 960 px focal: 18 degrees to the
    /// image's side edge), blurred by `blur_px`.
    fn wall_and_camera(blur_px: f64) -> FramesInView {
        let grid = VoxelGrid::new(0.5, Point3::origin());
        let points = (-40..40)
            .flat_map(|y| {
                (-20..20)
                    .map(move |z| Point3::new(0.45, f64::from(y) * 0.125, f64::from(z) * 0.125))
            })
            .collect();
        let cloud = PointCloud {
            frame_id: "map".into(),
            points,
            grid: None,
            mesh_spacing_m: None,
        };
        let map = SlamMap::on_grid(cloud, grid).unwrap();
        let looking_back = Matrix3::from_columns(&[Vector3::y(), -Vector3::z(), -Vector3::x()]);
        let shot = Shot {
            id: 0,
            camera: Isometry3::from_parts(
                Translation3::new(3.95, 0.0, 0.0),
                UnitQuaternion::from_matrix(&looking_back),
            ),
            lens: 0,
            blur_px: Some(blur_px),
        };
        let lens = Intrinsics::pinhole(640, 480, 960.0);
        FramesInView::of_shots(vec![shot], vec![lens], map, &ViewModel::default())
    }

    #[test]
    fn a_frame_sees_to_its_image_edge_beyond_the_viewing_cone_when_sharp() {
        let frames = wall_and_camera(0.5);
        let on_wall = |degrees_off_axis: f64| {
            let y = 3.5 * f64::to_radians(degrees_off_axis).tan();
            frames.finest_gsd_mm(&Point3::new(0.45, y, 0.0), &Vector3::x())
        };
        // 15 degrees off the axis: outside the 20-degree cone, inside the image.
        let gsd = on_wall(15.0).expect("in the image");
        let slant_m = 3.5 / 15f64.to_radians().cos();
        assert!((gsd - slant_m / 960.0 * 1000.0).abs() < 1e-6, "{gsd}");
        assert!(on_wall(0.0).is_some());
        // 25 degrees: beyond the image's edge.
        assert_eq!(on_wall(25.0), None);
        // Facing away from the camera.
        assert_eq!(
            frames.finest_gsd_mm(&Point3::new(0.45, 0.0, 0.0), &-Vector3::x()),
            None
        );
        // A blurred frame sees nothing.
        let blurred = wall_and_camera(10.0);
        assert_eq!(
            blurred.finest_gsd_mm(&Point3::new(0.45, 0.0, 0.0), &Vector3::x()),
            None
        );
    }
}
