//! Where detection matters: for each frame, the parts of its image that
//! show a patch of the surface it is among the best views of, by the View
//! model's measure. The `coverage` crate chooses them from the map and the
//! poses; detect runs the model only on the tiles that show them.

use std::collections::BTreeMap;

use crate::detection::BoxXyxy;

/// The best views of every patch, as the frames that give them.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BestViews {
    /// Views kept for each patch (`[detect] views_per_patch`).
    pub views_per_patch: u32,
    /// Patches of the surface chosen for: the exposed faces of the map's
    /// voxels.
    pub patches: u64,
    /// Of those, the ones some frame sees.
    pub patches_seen: u64,
    /// Every frame with a camera pose, by index; a frame not listed has none.
    pub frames: BTreeMap<u32, FrameViews>,
}

/// What one frame sees and is chosen for.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameViews {
    /// Patches it sees (in the image, facing it, not hidden).
    pub patches_seen: u32,
    /// The image boxes (pixels) of the patches it is among the best views
    /// of.
    pub best: Vec<BoxXyxy>,
}

impl BestViews {
    /// The image boxes of the patches frame `frame` is among the best
    /// views of.
    pub fn best_boxes(&self, frame: u32) -> &[BoxXyxy] {
        self.frames.get(&frame).map_or(&[], |v| v.best.as_slice())
    }

    /// Why a part `window` (pixels) of frame `frame` need not be run, or
    /// `None` when it shows a patch it is among the best views of.
    pub fn skip(&self, frame: u32, window: &BoxXyxy) -> Option<TileSkip> {
        let Some(views) = self.frames.get(&frame) else {
            return Some(TileSkip::NoPose);
        };
        if views.patches_seen == 0 {
            return Some(TileSkip::NoSurface);
        }
        let shows = |b: &BoxXyxy| {
            b.x0 < window.x1 && window.x0 < b.x1 && b.y0 < window.y1 && window.y0 < b.y1
        };
        (!views.best.iter().any(shows)).then_some(TileSkip::NotAmongBest)
    }
}

crate::kind! {
    /// Why a tile of a frame was not run.
    pub enum TileSkip("reason a tile was skipped") {
        /// Every patch of the map it shows is seen better by other frames.
        NotAmongBest = "not_among_best",
        /// Its frame shows no patch of the map within reach.
        NoSurface = "no_surface",
        /// Its frame has no camera pose, so localise could place nothing
        /// found in it.
        NoPose = "no_pose",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn b(x0: f32, y0: f32, x1: f32, y1: f32) -> BoxXyxy {
        BoxXyxy { x0, y0, x1, y1 }
    }

    #[test]
    fn a_tile_runs_when_it_shows_a_best_patch() {
        let mut best = BestViews::default();
        best.frames.insert(
            0,
            FrameViews {
                patches_seen: 3,
                best: vec![b(100.0, 100.0, 150.0, 140.0)],
            },
        );
        best.frames.insert(1, FrameViews::default());
        assert_eq!(best.skip(0, &b(0.0, 0.0, 120.0, 120.0)), None);
        assert_eq!(
            best.skip(0, &b(150.0, 0.0, 300.0, 300.0)),
            Some(TileSkip::NotAmongBest)
        );
        assert_eq!(
            best.skip(1, &b(0.0, 0.0, 640.0, 480.0)),
            Some(TileSkip::NoSurface)
        );
        assert_eq!(
            best.skip(2, &b(0.0, 0.0, 640.0, 480.0)),
            Some(TileSkip::NoPose)
        );
    }
}
