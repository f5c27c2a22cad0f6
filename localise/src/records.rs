//! The stage's outputs as records: `observations.parquet` (one row per
//! detection), `defects.parquet` (one row per candidate) and `defects.json`
//! (the candidates with every supporting view, for people and the review
//! queue). Columns are flat, angles in degrees, lengths in metres.

use polars::prelude::*;
use serde::{Deserialize, Serialize};

use crate::fusion::DefectCandidate;
use crate::observation::Observation;

/// One view of a defect candidate.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct ViewRecord {
    pub frame: u32,
    pub time_ns: i64,
    /// `[x0, y0, x1, y1]`, frame pixels.
    pub bbox: [f32; 4],
    pub score: f32,
    pub range_m: f64,
    pub incidence_deg: f64,
    pub gsd_mm: f64,
    pub length_m: Option<f64>,
    /// The box touches the image border.
    pub clipped: bool,
}

/// One defect candidate in `defects.json`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct DefectRecord {
    pub id: String,
    /// World frame, metres.
    pub position: [f64; 3],
    pub normal: [f64; 3],
    pub extent_min: [f64; 3],
    pub extent_max: [f64; 3],
    pub voxel: [i32; 3],
    pub face: String,
    pub length_m: Option<f64>,
    pub length_views: u32,
    /// The length is a lower bound from views the image border cuts.
    pub length_partial: bool,
    pub frames: u32,
    pub confidence: f64,
    pub max_score: f64,
    /// JPEG of the best view, relative to the run directory (none when its
    /// image could not be decoded).
    pub crop: Option<String>,
    pub best: ViewRecord,
    /// Every supporting view, in frame order.
    pub views: Vec<ViewRecord>,
}

fn view(o: &Observation) -> Option<ViewRecord> {
    let p = o.placement.as_ref()?;
    let d = &o.detection;
    let b = d.detection.bbox;
    Some(ViewRecord {
        frame: d.frame,
        time_ns: d.time_ns,
        bbox: [b.x0, b.y0, b.x1, b.y1],
        score: d.detection.score,
        range_m: p.hit.range,
        incidence_deg: p.hit.incidence.to_degrees(),
        gsd_mm: p.gsd_mm,
        length_m: p.length_m,
        clipped: o.clipped,
    })
}

impl DefectRecord {
    pub fn new(c: &DefectCandidate, observations: &[Observation], crop: Option<String>) -> Self {
        let views = c
            .observations
            .iter()
            .filter_map(|i| view(&observations[*i]))
            .collect();
        Self {
            id: c.id.clone(),
            position: c.position.coords.into(),
            normal: c.normal.into(),
            extent_min: c.extent[0].coords.into(),
            extent_max: c.extent[1].coords.into(),
            voxel: c.voxel.0,
            face: c.face.to_string(),
            length_m: c.length_m,
            length_views: c.length_views,
            length_partial: c.length_partial,
            frames: c.frames,
            confidence: c.confidence,
            max_score: c.max_score,
            crop,
            best: view(&observations[c.best]).expect("a candidate's views are placed"),
            views,
        }
    }
}

fn xyz(name: &str, values: impl Iterator<Item = Option<[f64; 3]>>) -> Vec<Column> {
    let mut columns: [Vec<Option<f64>>; 3] = Default::default();
    for v in values {
        for (a, c) in columns.iter_mut().enumerate() {
            c.push(v.map(|v| v[a]));
        }
    }
    ["x", "y", "z"]
        .iter()
        .zip(columns)
        .map(|(axis, c)| Column::new(format!("{name}{axis}").into(), c))
        .collect()
}

/// `observations.parquet`: every detection, placed or not, with the reason.
pub fn observations_table(
    observations: &[Observation],
    defect_of: &[Option<String>],
) -> PolarsResult<DataFrame> {
    let o = observations;
    let p = |f: &dyn Fn(&crate::observation::Placement) -> f64| {
        o.iter()
            .map(|o| o.placement.as_ref().map(f))
            .collect::<Vec<Option<f64>>>()
    };
    let b = |f: &dyn Fn(&detect::boxes::BoxXyxy) -> f32| {
        o.iter()
            .map(|o| f(&o.detection.detection.bbox))
            .collect::<Vec<f32>>()
    };
    let mut columns = vec![
        Column::new(
            "frame".into(),
            o.iter().map(|o| o.detection.frame).collect::<Vec<u32>>(),
        ),
        Column::new(
            "time_ns".into(),
            o.iter().map(|o| o.detection.time_ns).collect::<Vec<i64>>(),
        ),
        Column::new("x0".into(), b(&|b| b.x0)),
        Column::new("y0".into(), b(&|b| b.y0)),
        Column::new("x1".into(), b(&|b| b.x1)),
        Column::new("y1".into(), b(&|b| b.y1)),
        Column::new(
            "score".into(),
            o.iter()
                .map(|o| o.detection.detection.score)
                .collect::<Vec<f32>>(),
        ),
        Column::new(
            "outcome".into(),
            o.iter().map(|o| o.outcome.as_str()).collect::<Vec<&str>>(),
        ),
    ];
    columns.extend(xyz(
        "",
        o.iter()
            .map(|o| o.placement.as_ref().map(|p| p.centre.coords.into())),
    ));
    columns.extend(xyz(
        "n",
        o.iter()
            .map(|o| o.placement.as_ref().map(|p| p.hit.normal.into())),
    ));
    for (a, axis) in ["x", "y", "z"].iter().enumerate() {
        columns.push(Column::new(
            format!("voxel_{axis}").into(),
            o.iter()
                .map(|o| o.placement.as_ref().map(|p| p.hit.voxel.0[a]))
                .collect::<Vec<Option<i32>>>(),
        ));
    }
    columns.extend([
        Column::new(
            "face".into(),
            o.iter()
                .map(|o| o.placement.as_ref().map(|p| p.hit.face()))
                .collect::<Vec<Option<&str>>>(),
        ),
        Column::new("range_m".into(), p(&|p| p.hit.range)),
        Column::new("incidence_deg".into(), p(&|p| p.hit.incidence.to_degrees())),
        Column::new("gsd_mm".into(), p(&|p| p.gsd_mm)),
        Column::new(
            "length_m".into(),
            o.iter()
                .map(|o| o.placement.as_ref().and_then(|p| p.length_m))
                .collect::<Vec<Option<f64>>>(),
        ),
        Column::new("radius_m".into(), p(&|p| p.radius)),
        Column::new(
            "traced_px".into(),
            o.iter().map(|o| o.traced_px).collect::<Vec<u32>>(),
        ),
        Column::new(
            "clipped".into(),
            o.iter().map(|o| o.clipped).collect::<Vec<bool>>(),
        ),
        Column::new("defect".into(), defect_of.to_vec()),
    ]);
    DataFrame::new(o.len(), columns)
}

/// `defects.parquet`: one row per candidate, its best view inline.
pub fn defects_table(defects: &[DefectRecord]) -> PolarsResult<DataFrame> {
    let d = defects;
    let f = |get: &dyn Fn(&DefectRecord) -> f64| d.iter().map(get).collect::<Vec<f64>>();
    let mut columns = vec![Column::new(
        "id".into(),
        d.iter().map(|d| d.id.as_str()).collect::<Vec<&str>>(),
    )];
    columns.extend(xyz("", d.iter().map(|d| Some(d.position))));
    columns.extend(xyz("n", d.iter().map(|d| Some(d.normal))));
    columns.extend(xyz("min_", d.iter().map(|d| Some(d.extent_min))));
    columns.extend(xyz("max_", d.iter().map(|d| Some(d.extent_max))));
    for (a, axis) in ["x", "y", "z"].iter().enumerate() {
        columns.push(Column::new(
            format!("voxel_{axis}").into(),
            d.iter().map(|d| d.voxel[a]).collect::<Vec<i32>>(),
        ));
    }
    columns.extend([
        Column::new(
            "face".into(),
            d.iter().map(|d| d.face.as_str()).collect::<Vec<&str>>(),
        ),
        Column::new(
            "length_m".into(),
            d.iter().map(|d| d.length_m).collect::<Vec<Option<f64>>>(),
        ),
        Column::new(
            "length_views".into(),
            d.iter().map(|d| d.length_views).collect::<Vec<u32>>(),
        ),
        Column::new(
            "length_partial".into(),
            d.iter().map(|d| d.length_partial).collect::<Vec<bool>>(),
        ),
        Column::new(
            "frames".into(),
            d.iter().map(|d| d.frames).collect::<Vec<u32>>(),
        ),
        Column::new("confidence".into(), f(&|d| d.confidence)),
        Column::new("max_score".into(), f(&|d| d.max_score)),
        Column::new(
            "best_frame".into(),
            d.iter().map(|d| d.best.frame).collect::<Vec<u32>>(),
        ),
        Column::new("best_range_m".into(), f(&|d| d.best.range_m)),
        Column::new("best_incidence_deg".into(), f(&|d| d.best.incidence_deg)),
        Column::new("best_gsd_mm".into(), f(&|d| d.best.gsd_mm)),
    ]);
    for (k, name) in ["best_x0", "best_y0", "best_x1", "best_y1"]
        .iter()
        .enumerate()
    {
        columns.push(Column::new(
            (*name).into(),
            d.iter().map(|d| d.best.bbox[k]).collect::<Vec<f32>>(),
        ));
    }
    columns.push(Column::new(
        "crop".into(),
        d.iter()
            .map(|d| d.crop.as_deref())
            .collect::<Vec<Option<&str>>>(),
    ));
    DataFrame::new(d.len(), columns)
}
