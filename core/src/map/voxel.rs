//! Sparse voxel occupancy: which cubes of space the map's points fall in.

use std::collections::HashMap;

use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

use super::side::FaceSide;
use crate::table::{Column, Columns, DataFrame, PolarsResult, axes_names, read_axes, write_axes};

/// Integer coordinates of a voxel in a grid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct VoxelIndex(pub [i32; 3]);

/// A voxel index's columns: `{name}_x`, `{name}_y`, `{name}_z`.
impl Columns for VoxelIndex {
    fn write(prefix: &str, name: &str, values: &[&Self], out: &mut Vec<Column>) {
        let indices: Vec<&[i32; 3]> = values.iter().map(|v| &v.0).collect();
        write_axes(
            prefix,
            axes(name).each_ref().map(String::as_str),
            &indices,
            out,
        );
    }

    fn read(prefix: &str, name: &str, table: &DataFrame) -> PolarsResult<Vec<Self>> {
        let indices = read_axes(prefix, axes(name).each_ref().map(String::as_str), table)?;
        Ok(indices.into_iter().map(VoxelIndex).collect())
    }

    fn names(prefix: &str, name: &str, out: &mut Vec<String>) {
        axes_names::<i32>(prefix, &axes(name).each_ref().map(String::as_str), out);
    }
}

fn axes(name: &str) -> [String; 3] {
    ["x", "y", "z"].map(|axis| format!("{name}_{axis}"))
}

impl VoxelIndex {
    /// The 6 face-sharing neighbours.
    pub fn face_neighbours(self) -> [VoxelIndex; 6] {
        let [x, y, z] = self.0;
        [
            VoxelIndex([x + 1, y, z]),
            VoxelIndex([x - 1, y, z]),
            VoxelIndex([x, y + 1, z]),
            VoxelIndex([x, y - 1, z]),
            VoxelIndex([x, y, z + 1]),
            VoxelIndex([x, y, z - 1]),
        ]
    }

    /// The 26 voxels sharing a face, edge or corner.
    pub fn neighbours(self) -> impl Iterator<Item = VoxelIndex> {
        let [x, y, z] = self.0;
        (-1..=1)
            .flat_map(|dx| (-1..=1).flat_map(move |dy| (-1..=1).map(move |dz| [dx, dy, dz])))
            .filter(|d| *d != [0, 0, 0])
            .map(move |[dx, dy, dz]| VoxelIndex([x + dx, y + dy, z + dz]))
    }
}

/// A grid of cubic voxels: the geometry only, mapping world points to voxels.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct VoxelGrid {
    /// Edge length of a voxel, metres.
    pub resolution: f64,
    /// World position of the corner of voxel `[0, 0, 0]`.
    pub origin: Point3<f64>,
}

/// The grid at [`DEFAULT_RESOLUTION`](super::DEFAULT_RESOLUTION), anchored
/// at the world origin (without a plan whose grid to share).
impl Default for VoxelGrid {
    fn default() -> Self {
        Self::new(super::DEFAULT_RESOLUTION, Point3::origin())
    }
}

impl VoxelGrid {
    pub fn new(resolution: f64, origin: Point3<f64>) -> Self {
        assert!(resolution > 0.0, "voxel resolution must be positive");
        Self { resolution, origin }
    }

    pub fn voxel_of(&self, p: &Point3<f64>) -> VoxelIndex {
        let v = (p - self.origin) / self.resolution;
        VoxelIndex([v.x.floor() as i32, v.y.floor() as i32, v.z.floor() as i32])
    }

    pub fn center(&self, v: VoxelIndex) -> Point3<f64> {
        let [x, y, z] = v.0;
        self.origin
            + Vector3::new(f64::from(x) + 0.5, f64::from(y) + 0.5, f64::from(z) + 0.5)
                * self.resolution
    }
}

/// Voxels occupied by map points, with the number of points in each.
#[derive(Debug, Clone)]
pub struct VoxelMap {
    pub grid: VoxelGrid,
    occupied: HashMap<VoxelIndex, u32>,
}

impl VoxelMap {
    /// Voxelise points; a voxel is occupied when at least `min_points` fall in it
    /// (1 keeps every return; more suppresses isolated noise).
    pub fn from_points(grid: VoxelGrid, points: &[Point3<f64>], min_points: u32) -> Self {
        let mut occupied: HashMap<VoxelIndex, u32> = HashMap::new();
        for p in points {
            *occupied.entry(grid.voxel_of(p)).or_default() += 1;
        }
        occupied.retain(|_, n| *n >= min_points.max(1));
        Self { grid, occupied }
    }

    pub fn is_occupied(&self, v: VoxelIndex) -> bool {
        self.occupied.contains_key(&v)
    }

    /// Number of map points in a voxel.
    pub fn points_in(&self, v: VoxelIndex) -> u32 {
        self.occupied.get(&v).copied().unwrap_or(0)
    }

    pub fn len(&self) -> usize {
        self.occupied.len()
    }

    pub fn is_empty(&self) -> bool {
        self.occupied.is_empty()
    }

    pub fn voxels(&self) -> impl Iterator<Item = VoxelIndex> + '_ {
        self.occupied.keys().copied()
    }

    /// Occupied voxels among the 26 neighbours of `v`.
    pub fn occupied_neighbours(&self, v: VoxelIndex) -> impl Iterator<Item = VoxelIndex> + '_ {
        v.neighbours().filter(|n| self.is_occupied(*n))
    }

    /// Sides of `v` not shared with another occupied voxel.
    pub fn exposed_faces(&self, v: VoxelIndex) -> impl Iterator<Item = FaceSide> + '_ {
        FaceSide::ALL
            .into_iter()
            .filter(move |side| !self.is_occupied(side.neighbour(v)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn world_voxel_round_trip_and_neighbours() {
        let grid = VoxelGrid::new(0.5, Point3::new(-1.0, 0.0, 0.0));
        assert_eq!(
            grid.voxel_of(&Point3::new(-1.0, 0.0, 0.0)),
            VoxelIndex([0, 0, 0])
        );
        assert_eq!(
            grid.voxel_of(&Point3::new(-1.01, 0.49, 0.5)),
            VoxelIndex([-1, 0, 1])
        );
        assert_eq!(
            grid.center(VoxelIndex([0, 0, 0])),
            Point3::new(-0.75, 0.25, 0.25)
        );
        let pts = [
            Point3::new(-0.9, 0.1, 0.1),
            Point3::new(-0.8, 0.1, 0.1),
            Point3::new(-0.4, 0.1, 0.1),
            Point3::new(5.0, 5.0, 5.0),
        ];
        let map = VoxelMap::from_points(grid, &pts, 1);
        assert_eq!(map.len(), 3);
        assert_eq!(map.points_in(VoxelIndex([0, 0, 0])), 2);
        assert_eq!(map.occupied_neighbours(VoxelIndex([0, 0, 0])).count(), 1);
        assert_eq!(map.exposed_faces(VoxelIndex([0, 0, 0])).count(), 5);
        assert_eq!(VoxelMap::from_points(grid, &pts, 2).len(), 1);
        assert_eq!(VoxelIndex([0, 0, 0]).neighbours().count(), 26);
    }
}
