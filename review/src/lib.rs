//! The human review queue: inspectors accept or reject each proposed crack.
//! `store` keeps the decisions (SQLite, one transaction per decision, an
//! audit trail of who decided what, when, and what it replaced); `queue`
//! orders and filters the candidates; `pictures` draws what a reviewer
//! judges by; `pages` renders the HTML; `server` is the web application
//! (`postflight review serve`); `export` writes the decisions and the
//! accepted defects for others.

pub mod export;
pub mod pages;
pub mod pictures;
pub mod queue;
pub mod server;
pub mod since;
pub mod store;

pub use queue::{Filter, Queue};
pub use server::{Listening, ServeOptions, serve};
pub use store::{Decision, InvalidDecision, ReviewError, ReviewStore, Verdict};

#[cfg(test)]
pub(crate) mod testing {
    use postflight_core::outputs::localise::DefectRecord;

    /// A defect candidate with one view, for unit tests.
    pub fn defect(id: &str, confidence: f64) -> DefectRecord {
        let view = serde_json::json!({
            "frame": 1, "time_ns": 0, "bbox": [0.0, 0.0, 10.0, 10.0], "score": confidence,
            "range_m": 3.0, "incidence_deg": 10.0, "gsd_mm": 3.0, "length_m": 0.5, "clipped": false
        });
        serde_json::from_value(serde_json::json!({
            "id": id, "position": [0.0, 0.0, 0.0], "normal": [1.0, 0.0, 0.0],
            "extent_min": [0.0, 0.0, 0.0], "extent_max": [0.0, 0.5, 0.0], "voxel": [0, 0, 0],
            "face": "+x", "length_m": 0.5, "length_views": 1,
            "frames": 1, "confidence": confidence, "max_score": confidence, "crop": null,
            "evidence": {
                "view_faults": [], "view_gsd_mm": 3.0, "blur_px": null, "length": "measured",
                "min_measurable_width_mm": 6.0, "reshoot": false
            },
            "best": view, "views": [view]
        }))
        .unwrap()
    }
}
