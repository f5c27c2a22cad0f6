//! How far a candidate's evidence can be trusted: each view judged by the
//! View model's rules (distance band, incidence, GSD, blur), whether the
//! length was measured and why not, the narrowest width the best view can
//! measure, and whether the spot must be shot again.

use postflight_core::ViewModel;
use postflight_core::outputs::localise::{Evidence, LengthStatus};
use postflight_core::view::Miss;

use crate::observation::Placement;

/// The View model's rules a view of a crack at `range_m` and `incidence_deg`
/// breaks, seen at the View model's GSD `gsd_mm` ([`ViewModel::gsd_mm`]) in
/// a frame blurred by `blur_px` (`None`: unknown, not judged). Not the
/// cone: the detector reads the whole image.
pub fn view_faults(
    view: &ViewModel,
    range_m: f64,
    incidence_deg: f64,
    gsd_mm: f64,
    blur_px: Option<f64>,
) -> Vec<Miss> {
    [
        view.distance_miss(range_m),
        view.incidence_miss(incidence_deg),
        view.gsd_miss(gsd_mm),
        view.blur_miss(blur_px),
    ]
    .into_iter()
    .flatten()
    .collect()
}

/// A candidate's evidence from its best view and its length's status.
pub fn evidence(best: &Placement, length: LengthStatus) -> Evidence {
    let reshoot = !best.view_faults.is_empty() || length.missing_reason().is_some();
    Evidence {
        view_faults: best.view_faults.clone(),
        view_gsd_mm: best.view_gsd_mm,
        blur_px: best.blur_px,
        length,
        min_measurable_width_mm: Evidence::MIN_WIDTH_PX * best.oblique_gsd_mm,
        reshoot,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::surface::SurfaceHit;
    use nalgebra::{Point3, Vector3};
    use postflight_core::map::VoxelIndex;
    use postflight_core::trace::Trace;

    #[test]
    fn every_rule_a_view_breaks_is_named() {
        let view = ViewModel::default();
        // A 1000 px focal length: GSD in mm/px is the range in metres.
        assert!(view_faults(&view, 4.0, 30.0, 4.0, Some(1.0)).is_empty());
        assert_eq!(
            view_faults(&view, 10.5, 70.0, 10.5, Some(4.0)),
            [
                Miss::TooFar,
                Miss::TooOblique,
                Miss::TooCoarse,
                Miss::Blurred
            ]
        );
        assert_eq!(view_faults(&view, 1.5, 0.0, 1.5, None), [Miss::TooClose]);
        // Within the band but coarse through a short lens.
        assert_eq!(view_faults(&view, 4.0, 0.0, 8.0, None), [Miss::TooCoarse]);
    }

    #[test]
    fn a_missing_length_or_a_broken_rule_asks_for_a_reshoot() {
        let centre = Point3::new(3.0, 0.0, 1.0);
        let sharp = Placement {
            sight: Default::default(),
            hit: SurfaceHit {
                point: centre,
                normal: Vector3::x(),
                voxel: VoxelIndex([6, 0, 2]),
                range: 3.0,
                incidence: 0.3,
            },
            centre,
            extent: [centre, centre],
            radius: 0.2,
            length_m: Some(0.4),
            oblique_gsd_mm: 3.5,
            view_gsd_mm: 3.0,
            blur_px: Some(0.5),
            view_faults: Vec::new(),
            width: None,
            crossed: None,
            camera_std_m: None,
            trace: Trace::default(),
            cut: Vec::new(),
            line: None,
        };
        let measured = evidence(&sharp, LengthStatus::Measured);
        assert!(!measured.reshoot);
        assert_eq!(measured.min_measurable_width_mm, 7.0);
        assert!(!evidence(&sharp, LengthStatus::Partial).reshoot);
        assert!(evidence(&sharp, LengthStatus::TooOblique).reshoot);
        let far = Placement {
            sight: Default::default(),
            view_faults: vec![Miss::TooFar],
            width: None,
            crossed: None,
            camera_std_m: None,
            ..sharp
        };
        assert!(evidence(&far, LengthStatus::Measured).reshoot);
    }
}
