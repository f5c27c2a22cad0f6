//! Photogrammetry reconstructions as pose sources for photo folders: a
//! COLMAP sparse model (text or binary: [`colmap`]) or an OpenSfM /
//! OpenDroneMap `reconstruction.json` ([`opensfm`]). Each registered
//! image's refined pose and lens replace what its tags say, matched to the
//! photos by file name; the reconstruction's points can be the map. A
//! reconstruction in a frame of its own (COLMAP's, or OpenSfM's without a
//! reference) is brought into the photos' frame by the similarity that
//! best puts its cameras on the photos' GPS positions ([`Similarity`]).

mod colmap;
mod opensfm;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Point3};
use postflight_core::Intrinsics;
use postflight_core::geo::{GeoOrigin, Geodetic};
use postflight_core::outputs::ingest::{
    ReconstructionFormat as Format, ReconstructionPlacedBy, ReconstructionSummary,
};
use postflight_core::similarity::Similarity;

/// One registered image: its lens and where its camera was.
#[derive(Debug, Clone, PartialEq)]
pub struct RegisteredImage {
    pub lens: Intrinsics,
    /// `T_reconstruction_camera` (optical axes: x right, y down, z forward).
    pub pose: Isometry3<f64>,
}

/// A reconstruction as read: images by file name (the last part of the
/// name it has there), its points, and where it is on the Earth when it
/// says.
#[derive(Debug, Clone)]
pub struct Reconstruction {
    pub path: PathBuf,
    pub format: Format,
    pub images: BTreeMap<String, RegisteredImage>,
    pub points: Vec<Point3<f64>>,
    /// The east-north-up frame its coordinates are in (OpenSfM's
    /// `reference_lla`); `None`: a frame of its own.
    pub reference: Option<Geodetic>,
}

impl Reconstruction {
    /// Read a COLMAP model directory or an OpenSfM `reconstruction.json`.
    pub fn load(path: &Path) -> Result<Self, String> {
        let r = if path.is_dir() {
            colmap::read(path)?
        } else {
            opensfm::read(path)?
        };
        if r.images.is_empty() {
            return Err("it has no registered images".into());
        }
        if let Some(p) = r
            .points
            .iter()
            .find(|p| !p.coords.iter().all(|v| v.is_finite()))
        {
            return Err(format!(
                "its point {}, {}, {} is not a place",
                p.x, p.y, p.z
            ));
        }
        Ok(r)
    }

    /// Put into the map frame at `origin`: by its own reference, else by
    /// the similarity that puts its cameras on `positions` (the photos'
    /// GPS positions in the map frame, by file name).
    pub fn place(
        self,
        origin: &GeoOrigin,
        positions: &BTreeMap<String, Point3<f64>>,
    ) -> Result<Placed, String> {
        let (similarity, placed_by) = match &self.reference {
            Some(at) => (
                Similarity::from_reference(at, origin),
                ReconstructionPlacedBy::Reference,
            ),
            None => {
                let (from, to): (Vec<Point3<f64>>, Vec<Point3<f64>>) = self
                    .images
                    .iter()
                    .filter_map(|(name, image)| {
                        let at = positions.get(name)?;
                        Some((Point3::from(image.pose.translation.vector), *at))
                    })
                    .unzip();
                let (similarity, rms_m) = Similarity::fit(&from, &to).map_err(|why| {
                    format!(
                        "it has no reference on the Earth, and its cameras cannot be fitted to the photos' GPS: {why}"
                    )
                })?;
                let photos = from.len();
                (similarity, ReconstructionPlacedBy::GpsFit { photos, rms_m })
            }
        };
        Ok(Placed {
            reconstruction: self,
            similarity,
            placed_by,
        })
    }
}

/// A reconstruction in the run's map frame.
pub struct Placed {
    pub reconstruction: Reconstruction,
    pub similarity: Similarity,
    pub placed_by: ReconstructionPlacedBy,
}

impl Placed {
    /// The registered image of a photo, in the map frame: its lens and
    /// camera pose (`T_map_camera`).
    pub fn image(&self, photo: &str) -> Option<(Intrinsics, Isometry3<f64>)> {
        let image = self.reconstruction.images.get(photo)?;
        Some((image.lens.clone(), self.similarity.pose(&image.pose)))
    }

    /// Its points in the map frame.
    pub fn points(&self) -> Vec<Point3<f64>> {
        let points = self.reconstruction.points.iter();
        points.map(|p| self.similarity.apply(p)).collect()
    }

    /// What `ingest.json` says of it, having posed `posed` photos.
    pub fn summary(&self, posed: u64) -> ReconstructionSummary {
        let r = &self.reconstruction;
        ReconstructionSummary {
            path: std::path::absolute(&r.path).unwrap_or_else(|_| r.path.clone()),
            format: r.format,
            images: r.images.len() as u64,
            posed,
            points: r.points.len() as u64,
            similarity: self.similarity,
            placed_by: self.placed_by,
        }
    }
}

/// The last part of an image's name in a reconstruction (COLMAP names
/// images by their path under its image folder).
fn file_name(name: &str) -> String {
    name.rsplit(['/', '\\']).next().unwrap_or(name).to_string()
}
