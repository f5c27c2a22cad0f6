//! Which View model judges each face: the run's, or that of the focus
//! region holding the face's voxel centre (the first listed, where regions
//! overlap).

use postflight_core::Intrinsics;
use postflight_core::ViewModel;
use postflight_core::map::{SlamMap, VoxelGrid};
use postflight_core::region::{FocusModel, RegionError};

use crate::cover::{FaceCover, Shot, cover};
use crate::face::Face;
use crate::settings::keys;

/// The View models of a set of faces.
#[derive(Debug, Clone)]
pub struct FaceModels {
    /// The run's model first, then each focus region's.
    models: Vec<ViewModel>,
    /// Each face's model (an index into `models`).
    of_face: Vec<usize>,
}

impl FaceModels {
    /// Each of `faces` under `base`, or under the focus region holding its
    /// voxel's centre.
    pub fn new(base: ViewModel, focus: &[FocusModel], faces: &[Face], grid: &VoxelGrid) -> Self {
        let models = std::iter::once(base)
            .chain(focus.iter().map(|f| f.view))
            .collect();
        let of_face = faces
            .iter()
            .map(|f| FocusModel::holding(focus, &grid.center(f.voxel)).map_or(0, |k| k + 1))
            .collect();
        Self { models, of_face }
    }

    /// Face `i`'s View model.
    pub fn of(&self, i: usize) -> &ViewModel {
        &self.models[self.of_face[i]]
    }

    /// The models, the run's first, and each model's faces (indices).
    pub fn groups(&self) -> impl Iterator<Item = (&ViewModel, Vec<usize>)> {
        self.models.iter().enumerate().filter_map(|(m, model)| {
            let faces: Vec<usize> = (0..self.of_face.len())
                .filter(|&i| self.of_face[i] == m)
                .collect();
            (!faces.is_empty()).then_some((model, faces))
        })
    }

    /// [`cover`] of faces `range` of the set (`faces` and `need` are that
    /// range), each face under its own model.
    #[allow(clippy::too_many_arguments)]
    pub fn cover(
        &self,
        range: std::ops::Range<usize>,
        faces: &[Face],
        need: &[u32],
        shots: &[Shot],
        lenses: &[Intrinsics],
        map: &SlamMap,
    ) -> Vec<FaceCover> {
        if self.models.len() == 1 {
            return cover(faces, need, shots, lenses, map, &self.models[0]);
        }
        let mut out: Vec<Option<FaceCover>> = vec![None; faces.len()];
        for (m, model) in self.models.iter().enumerate() {
            let mine: Vec<usize> = (0..faces.len())
                .filter(|&i| self.of_face[range.start + i] == m)
                .collect();
            if mine.is_empty() {
                continue;
            }
            let (f, n): (Vec<Face>, Vec<u32>) = mine.iter().map(|&i| (faces[i], need[i])).unzip();
            for (i, c) in mine
                .into_iter()
                .zip(cover(&f, &n, shots, lenses, map, model))
            {
                out[i] = Some(c);
            }
        }
        out.into_iter()
            .map(|c| c.expect("every face has a model"))
            .collect()
    }
}

/// Refuse focus regions that cannot work, naming the region.
pub fn check(focus: &[FocusModel]) -> Result<(), RegionError> {
    focus.iter().try_for_each(|f| f.check(keys::focus))
}
