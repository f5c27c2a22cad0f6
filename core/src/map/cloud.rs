//! Point clouds of the SLAM map, loaded from PLY, PCD, OctoMap, a survey's
//! LAS or LAZ (placed in the map frame by the flight's geo origin) or a
//! recorded `sensor_msgs/msg/PointCloud2`.

use std::path::Path;

use nalgebra::Point3;

use super::VoxelGrid;
use super::mesh::{Mesh, SAMPLE_SPACING_M};
use crate::crs::Crs;
use crate::error::Error;
use crate::geo::GeoOrigin;

/// A mesh's surface as points, [`SAMPLE_SPACING_M`] apart or as far as
/// its size needs ([`Mesh::spacing`]).
fn surface(mesh: &Mesh) -> Result<(Vec<Point3<f64>>, f64), String> {
    let spacing = mesh.spacing()?;
    Ok((mesh.surface_points(spacing), spacing))
}

/// Whether a file is a survey's point cloud (LAS or LAZ), by its extension.
fn is_survey(path: &Path) -> bool {
    let extension = path.extension().and_then(|e| e.to_str());
    extension.is_some_and(|e| e.eq_ignore_ascii_case("las") || e.eq_ignore_ascii_case("laz"))
}

/// The points of a map in its frame (usually the SLAM `map` frame).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PointCloud {
    pub frame_id: String,
    pub points: Vec<Point3<f64>>,
    /// The grid whose voxel centres the points are, when the map is a voxel
    /// map (an OctoMap's, at its resolution).
    pub grid: Option<VoxelGrid>,
    /// How far apart its points were sampled, metres, when the map is a
    /// mesh; farther than [`SAMPLE_SPACING_M`] for a mesh too large to
    /// sample so densely ([`PointCloud::coarsened`]).
    pub mesh_spacing_m: Option<f64>,
}

impl PointCloud {
    /// Load a PLY (a cloud, or a mesh sampled over its surface), OBJ mesh,
    /// PCD or OctoMap (`.bt`, `.ot`) file, chosen by its extension.
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
        let bytes =
            crate::user_file::read(path).map_err(|e| error(format!("{e}; check the path")))?;
        Self::parse(&bytes, &ext).map_err(error)
    }

    /// Load a map file ([`PointCloud::load`]), or a LAS or LAZ file in its
    /// coordinate reference system, converted into the map frame placed on
    /// the Earth by `origin`.
    pub fn load_placed(path: &Path, origin: Option<&GeoOrigin>) -> Result<Self, Error> {
        if !is_survey(path) {
            return Self::load(path);
        }
        let error = |why: String| Error::Map {
            path: path.to_owned(),
            why,
        };
        let bytes =
            crate::user_file::read(path).map_err(|e| error(format!("{e}; check the path")))?;
        let (points, crs) = super::las::parse(&bytes).map_err(error)?;
        let origin = origin.ok_or_else(|| {
            error(format!(
                "its points are in {crs}, but the flight is not placed on the Earth (no GPS fixes or geotagged photos); give a map in the flight's map frame"
            ))
        })?;
        let projection = crs.projection().map_err(error)?;
        let points = points
            .iter()
            .map(|p| Ok(origin.to_local(&projection.to_geodetic(p.x, p.y, p.z)?)))
            .collect::<Result<Vec<_>, String>>()
            .map_err(error)?;
        if points.is_empty() {
            return Err(error("the map has no points".into()));
        }
        Ok(Self {
            frame_id: crs.to_string(),
            points,
            grid: None,
            mesh_spacing_m: None,
        })
    }

    /// Whether a map file can be placed (a LAS or LAZ file says its CRS),
    /// from its header alone: checked before a run starts.
    pub fn check_placeable(path: &Path) -> Result<(), Error> {
        if !is_survey(path) {
            return Ok(());
        }
        super::las::crs_of_file(path)
            .and_then(Crs::projection)
            .map(|_| ())
            .map_err(|why| Error::Map {
                path: path.to_owned(),
                why,
            })
    }

    /// A map file's contents, by its extension (`ply`, `pcd`, `bt`, `ot`).
    pub fn parse(bytes: &[u8], extension: &str) -> Result<Self, String> {
        let octomap = |format| {
            let map = super::octomap::parse(bytes, format)?;
            Ok((
                map.points,
                Some(VoxelGrid::new(map.resolution, Point3::origin())),
                None,
            ))
        };
        let mesh = |mesh: Mesh| surface(&mesh).map(|(points, at)| (points, None, Some(at)));
        let (points, grid, mesh_spacing_m) = match extension {
            "ply" => super::ply::parse(bytes).and_then(|ply| match ply.triangles.is_empty() {
                true => Ok((ply.points, None, None)),
                false => mesh(Mesh {
                    vertices: ply.points,
                    triangles: ply.triangles,
                }),
            }),
            "obj" => std::str::from_utf8(bytes)
                .map_err(|_| "the OBJ file is not text".to_string())
                .and_then(super::mesh::parse_obj)
                .and_then(mesh),
            "pcd" => super::pcd::parse(bytes).map(|points| (points, None, None)),
            "bt" => octomap(super::octomap::Format::Binary),
            "ot" => octomap(super::octomap::Format::Full),
            "las" | "laz" => Err(
                "a LAS or LAZ map is placed by the flight's geo origin; give it as the run's --map"
                    .into(),
            ),
            _ => Err(
                "unknown map format; give a .ply, .pcd, .obj, .las, .laz, or OctoMap .bt or .ot file"
                    .into(),
            ),
        }?;
        // Organised clouds (PCL's) hold NaN where the sensor had no return:
        // no point there.
        let mut points = points;
        points.retain(|p| p.coords.iter().all(|v| v.is_finite()));
        if points.is_empty() {
            return Err("the map has no points (none with finite coordinates)".into());
        }
        Ok(Self {
            frame_id: String::new(),
            points,
            grid,
            mesh_spacing_m,
        })
    }

    /// What to warn of where the map is a mesh sampled coarser than
    /// [`SAMPLE_SPACING_M`] to keep within its point budget.
    pub fn coarsened(&self) -> Option<String> {
        let spacing = self.mesh_spacing_m.filter(|s| *s > SAMPLE_SPACING_M)?;
        Some(format!(
            "the map's mesh is too large to sample every {SAMPLE_SPACING_M} m within {} points: sampled every {spacing:.2} m, so cracks are placed on a coarser surface; give a mesh of the inspected part only for finer placement",
            super::mesh::MAX_SURFACE_POINTS
        ))
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
