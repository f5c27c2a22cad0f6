//! The stage's results as the records of its files (see
//! `postflight_core::outputs::localise`): a candidate with its views, and
//! each detection with where it was placed.

use nalgebra::Point3;
use postflight_core::outputs::localise::{
    DefectRecord, ObservationRecord, PlacedRecord, ViewRecord, WidthRecord,
};
use postflight_core::trace::Trace;

use postflight_core::condition::CrackLimits;
use postflight_core::structure::Place;

use crate::fusion::DefectCandidate;
use crate::observation::Observation;

/// A placed observation as a view of its candidate.
fn view(o: &Observation) -> Option<ViewRecord> {
    ViewRecord::of(&observation_record(o, None))
}

/// A candidate with its views; `crop` is its best view's JPEG, relative to
/// the run directory, and `limits` put its width in a condition state.
pub fn defect_record(
    c: &DefectCandidate,
    observations: &[Observation],
    crop: Option<String>,
    place: Option<Place>,
    limits: &CrackLimits,
) -> DefectRecord {
    DefectRecord {
        element: place.as_ref().map(|p| p.element.clone()),
        place: place.map(|p| p.to_string()),
        id: c.id.clone(),
        position: c.position.coords.into(),
        position_uncertainty_m: c.position_uncertainty_m,
        normal: c.normal.into(),
        extent_min: c.extent[0].coords.into(),
        extent_max: c.extent[1].coords.into(),
        voxel: c.voxel.0,
        face: c.face,
        length_m: c.length_m,
        length_views: c.length_views,
        trace: c.trace.clone(),
        frames: c.frames,
        confidence: c.confidence,
        max_score: c.max_score,
        evidence: c.evidence.clone(),
        width: c.width.map(|w| along_the_trace(w, &c.trace)),
        condition: c.width.as_ref().and_then(|w| limits.state_of(w)),
        crop,
        best: view(&observations[c.best]).expect("a candidate's views are placed"),
        views: c
            .observations
            .iter()
            .filter_map(|i| view(&observations[*i]))
            .collect(),
    }
}

/// `width` with its widest stretch placed along the candidate's `trace`.
fn along_the_trace(mut width: WidthRecord, trace: &Trace) -> WidthRecord {
    if let Some(w) = &mut width.widest {
        w.along_m = trace.along(&Point3::from(w.at));
    }
    width
}

/// A detection as `observations.parquet` holds it; `defect` is the
/// candidate it supports.
pub fn observation_record(o: &Observation, defect: Option<String>) -> ObservationRecord {
    let d = &o.detection;
    ObservationRecord {
        frame: d.frame,
        time_ns: d.time_ns,
        bbox: d.detection.bbox,
        score: d.detection.score,
        outcome: o.outcome,
        placed: o.placement.as_ref().map(|p| PlacedRecord {
            centre: p.centre.coords.into(),
            normal: p.hit.normal.into(),
            voxel: p.hit.voxel,
            face: p.hit.face(),
            range_m: p.hit.range,
            incidence_deg: p.hit.incidence.to_degrees(),
            oblique_gsd_mm: p.oblique_gsd_mm,
            length_m: p.length_m,
            radius_m: p.radius,
        }),
        traced_px: o.traced_px,
        clipped: o.clipped,
        defect,
    }
}
