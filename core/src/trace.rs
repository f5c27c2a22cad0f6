//! A crack's trace on the structure: its centre line as polylines (the main
//! line and its branches) in the map frame, metres. Tables hold it as WKT
//! (`MULTILINESTRING Z`, millimetre precision), which DuckDB's spatial
//! extension, shapely and GeoPandas read.

use std::str::FromStr;

use nalgebra::{Isometry3, Point3};
use polars::prelude::{Column, PolarsResult, polars_err};
use serde::{Deserialize, Serialize};
use wkt::types::{Coord, Dimension, LineString, MultiLineString};

use crate::table::Cell;

/// The polylines of a crack's centre line, world frame, metres; empty when
/// no view traced it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Trace(pub Vec<Vec<[f64; 3]>>);

/// A trace's column holds its WKT (null when empty), the form DuckDB's
/// spatial extension and GeoPandas read.
impl Cell for Trace {
    fn column(name: &str, values: &[&Self]) -> Column {
        let wkt: Vec<Option<String>> = values.iter().map(|t| t.wkt()).collect();
        Column::new(name.into(), wkt)
    }

    fn values(column: &Column) -> PolarsResult<Vec<Self>> {
        let texts = <Option<String> as Cell>::values(column)?;
        texts
            .into_iter()
            .enumerate()
            .map(|(i, text)| match text {
                Some(text) => Self::from_wkt(&text).map_err(
                    |why| polars_err!(ComputeError: "column {} in row {i} is no trace: {why}", column.name()),
                ),
                None => Ok(Self::default()),
            })
            .collect()
    }

    fn absent() -> Option<Self> {
        Some(Self::default())
    }
}

impl Trace {
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Length along every polyline, metres.
    pub fn length_m(&self) -> f64 {
        self.0
            .iter()
            .flat_map(|line| line.windows(2))
            .map(|w| distance(&w[0], &w[1]))
            .sum()
    }

    /// As WKT (`MULTILINESTRING Z`), to the millimetre; `None` when empty.
    pub fn wkt(&self) -> Option<String> {
        let mm = |v: f64| (v * 1000.0).round() / 1000.0;
        let lines = self.0.iter().map(|line| {
            let coords = line.iter().map(|p| Coord {
                x: mm(p[0]),
                y: mm(p[1]),
                z: Some(mm(p[2])),
                m: None,
            });
            LineString::new(coords.collect(), Dimension::XYZ)
        });
        (!self.is_empty())
            .then(|| MultiLineString::new(lines.collect(), Dimension::XYZ).to_string())
    }

    /// A trace from WKT, as [`Self::wkt`] writes it.
    pub fn from_wkt(text: &str) -> Result<Self, String> {
        let lines = match wkt::Wkt::<f64>::from_str(text)? {
            wkt::Wkt::MultiLineString(m) if m.dimension() == Dimension::XYZ => m.into_inner().0,
            _ => return Err(format!("not a MULTILINESTRING Z: {text:.40}")),
        };
        let point = |c: &Coord<f64>| [c.x, c.y, c.z.unwrap_or_default()];
        Ok(Self(
            lines
                .iter()
                .map(|l| l.coords().iter().map(point).collect())
                .collect(),
        ))
    }

    /// The trace moved by `iso` (into another flight's frame).
    pub fn transformed(&self, iso: &Isometry3<f64>) -> Self {
        let moved = |p: &[f64; 3]| (iso * Point3::from(*p)).coords.into();
        Self(
            self.0
                .iter()
                .map(|l| l.iter().map(moved).collect())
                .collect(),
        )
    }

    /// Distance from `p` to its nearest polyline, metres (infinite when
    /// empty).
    pub fn distance_to(&self, p: &Point3<f64>) -> f64 {
        distance_to_lines(p, self.0.iter().map(|l| l.iter().map(|q| Point3::from(*q))))
    }

    /// How far along it the point nearest `p` is, metres: from its first
    /// polyline's first point, each polyline after the last; `None` when
    /// empty.
    pub fn along(&self, p: &Point3<f64>) -> Option<f64> {
        let mut nearest: Option<(f64, f64)> = None;
        let mut walked = 0.0;
        for line in &self.0 {
            let points: Vec<Point3<f64>> = line.iter().map(|q| Point3::from(*q)).collect();
            if let [only] = points.as_slice() {
                let d = (p - only).norm();
                if nearest.is_none_or(|(best, _)| d < best) {
                    nearest = Some((d, walked));
                }
            }
            for w in points.windows(2) {
                let on = closest_on_segment(p, &w[0], &w[1]);
                let d = (p - on).norm();
                if nearest.is_none_or(|(best, _)| d < best) {
                    nearest = Some((d, walked + (on - w[0]).norm()));
                }
                walked += (w[1] - w[0]).norm();
            }
        }
        nearest.map(|(_, along)| along)
    }

    /// Length of its lines farther than `apart` from `other`, counting only
    /// the stretches `counted` accepts (each judged at its middle), metres.
    pub fn length_beyond(
        &self,
        other: &Trace,
        apart: f64,
        counted: impl Fn(&Point3<f64>) -> bool,
    ) -> f64 {
        self.0
            .iter()
            .flat_map(|line| line.windows(2))
            .flat_map(|w| stretches(Point3::from(w[0]), Point3::from(w[1])))
            .filter(|(middle, _)| other.distance_to(middle) > apart && counted(middle))
            .map(|(_, length)| length)
            .sum()
    }
}

/// Distance from `p` to the nearest of `lines` (polylines; a lone point
/// counts as itself), metres; infinite when there are none.
pub fn distance_to_lines<L>(p: &Point3<f64>, lines: L) -> f64
where
    L: IntoIterator,
    L::Item: IntoIterator<Item = Point3<f64>>,
{
    let mut nearest = f64::INFINITY;
    for line in lines {
        let mut from: Option<Point3<f64>> = None;
        for q in line {
            let on = from.map_or(q, |a| closest_on_segment(p, &a, &q));
            nearest = nearest.min((p - on).norm());
            from = Some(q);
        }
    }
    nearest
}

/// The point of the segment `a`–`b` nearest `p`.
pub fn closest_on_segment(p: &Point3<f64>, a: &Point3<f64>, b: &Point3<f64>) -> Point3<f64> {
    let ab = b - a;
    let t = if ab.norm_squared() > 0.0 {
        ((p - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0)
    } else {
        0.0
    };
    a + ab * t
}

/// Stretches a segment is judged in, metres: short beside a crack's
/// change and its matching tolerance.
const STRETCH_M: f64 = 0.01;

/// A segment cut into stretches of at most [`STRETCH_M`]: each one's middle
/// and length.
fn stretches(a: Point3<f64>, b: Point3<f64>) -> impl Iterator<Item = (Point3<f64>, f64)> {
    let length = (b - a).norm();
    let n = (length / STRETCH_M).ceil().max(1.0) as usize;
    (0..n).map(move |k| {
        (
            a + (b - a) * ((k as f64 + 0.5) / n as f64),
            length / n as f64,
        )
    })
}

fn distance(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>().sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_trace_round_trips_through_wkt_to_the_millimetre() {
        let trace = Trace(vec![
            vec![[1.0, 2.0, 3.0], [1.5, 2.0, 3.0], [1.5, 2.4, 3.0]],
            vec![[-7.25, 0.0, 0.001]],
        ]);
        let text = trace.wkt().unwrap();
        assert_eq!(
            text,
            "MULTILINESTRING Z((1 2 3,1.5 2 3,1.5 2.4 3),(-7.25 0 0.001))"
        );
        assert_eq!(Trace::from_wkt(&text).unwrap(), trace);
        assert!((trace.length_m() - 0.9).abs() < 1e-12);
        assert_eq!(Trace::default().wkt(), None);
        assert!(Trace::from_wkt("POINT (1 2)").is_err());
        assert!(Trace::from_wkt("MULTILINESTRING ((1 2, 3 4))").is_err());
    }

    #[test]
    fn the_length_beyond_another_trace_is_what_runs_on_past_it() {
        let earlier = Trace(vec![vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]]);
        // 3 cm off it, then on 0.5 m past its end.
        let later = Trace(vec![vec![[0.0, 0.03, 0.0], [1.5, 0.03, 0.0]]]);
        let beyond = later.length_beyond(&earlier, 0.1, |_| true);
        // Past x = 1.0 + sqrt(0.1^2 - 0.03^2).
        assert!((beyond - (0.5 - 0.0954)).abs() < 0.011, "{beyond}");
        assert_eq!(earlier.length_beyond(&later, 0.1, |_| true), 0.0);
        // Only where it is counted.
        let counted = later.length_beyond(&earlier, 0.1, |p| p.x > 1.3);
        assert!((counted - 0.2).abs() < 0.011, "{counted}");
        let moved = earlier.transformed(&Isometry3::translation(0.0, 0.0, 2.0));
        assert!((moved.distance_to(&Point3::new(0.5, 0.0, 0.0)) - 2.0).abs() < 1e-12);
        assert_eq!(
            Trace::default().distance_to(&Point3::origin()),
            f64::INFINITY
        );
    }
}
