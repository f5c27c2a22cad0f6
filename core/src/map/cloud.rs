//! Point clouds of the SLAM map, loaded from PLY, PCD or a recorded
//! `sensor_msgs/msg/PointCloud2`.

use std::path::Path;

use nalgebra::Point3;

use super::VoxelGrid;
use crate::error::Error;

/// The points of a map in its frame (usually the SLAM `map` frame).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointCloud {
    pub frame_id: String,
    pub points: Vec<Point3<f64>>,
    /// The grid whose voxel centres the points are, when the map is a voxel
    /// map (an OctoMap's, at its resolution).
    pub grid: Option<VoxelGrid>,
}

impl PointCloud {
    /// Load a PLY, PCD or OctoMap (`.bt`, `.ot`) file, chosen by its extension.
    pub fn load(path: &Path) -> Result<Self, Error> {
        let error = |why: String| Error::Map {
            path: path.to_owned(),
            why,
        };
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .unwrap_or_default();
        let bytes = std::fs::read(path).map_err(|e| error(format!("{e}; check the path")))?;
        Self::parse(&bytes, &ext).map_err(error)
    }

    /// A map file's contents, by its extension (`ply`, `pcd`, `bt`, `ot`).
    pub fn parse(bytes: &[u8], extension: &str) -> Result<Self, String> {
        let octomap = |format| {
            let map = super::octomap::parse(bytes, format)?;
            Ok((
                map.points,
                Some(VoxelGrid::new(map.resolution, Point3::origin())),
            ))
        };
        let (points, grid) = match extension {
            "ply" => super::ply::parse(bytes).map(|points| (points, None)),
            "pcd" => super::pcd::parse(bytes).map(|points| (points, None)),
            "bt" => octomap(super::octomap::Format::Binary),
            "ot" => octomap(super::octomap::Format::Full),
            _ => Err("unknown map format; give a .ply, .pcd, or OctoMap .bt or .ot file".into()),
        }?;
        if points.is_empty() {
            return Err("the map has no points".into());
        }
        Ok(Self {
            frame_id: String::new(),
            points,
            grid,
        })
    }

    pub fn len(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Axis-aligned bounds `(min, max)`; `None` when empty.
    pub fn bounds(&self) -> Option<(Point3<f64>, Point3<f64>)> {
        let first = *self.points.first()?;
        Some(
            self.points
                .iter()
                .fold((first, first), |(lo, hi), p| (lo.inf(p), hi.sup(p))),
        )
    }
}
