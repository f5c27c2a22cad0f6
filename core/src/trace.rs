//! A crack's trace on the structure: its centre line as polylines (the main
//! line and its branches) in the map frame, metres. Tables hold it as WKT
//! (`MULTILINESTRING Z`, millimetre precision), which DuckDB's spatial
//! extension, shapely and GeoPandas read.

use std::str::FromStr;

use serde::{Deserialize, Serialize};
use wkt::types::{Coord, Dimension, LineString, MultiLineString};

/// The polylines of a crack's centre line, world frame, metres; empty when
/// no view traced it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Trace(pub Vec<Vec<[f64; 3]>>);

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
}
