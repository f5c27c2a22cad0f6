//! Which tiles of each frame run: with the best views of the map's patches
//! ([`BestViews`], chosen by the `coverage` crate from the poses and the
//! map), for each patch a frame is among the best views of, the tile that
//! shows most of it (a frame not tiled runs whole); else every tile and
//! the whole frame beside them. A
//! share of the flight ([`Shard`]) is a run of frames holding its share of
//! the tiles to run, not of the photos.

use postflight_core::Frame;
use postflight_core::best_views::{BestViews, TileSkip};
use postflight_core::detection::BoxXyxy;
use postflight_core::kind::Counts;
use postflight_core::outputs::detect::{Shard, TileChoice};

use crate::stage::DetectOptions;
use crate::tiles::{Window, windows};
use crate::views::Feed;

/// Which tiles a detect runs.
#[derive(Debug, Clone, Copy)]
pub struct TilesToRun<'a> {
    /// How they are chosen: with [`TileChoice::BestViews`], by `best`.
    pub choice: TileChoice,
    pub best: Option<&'a BestViews>,
    /// Only this share of the flight's frames.
    pub shard: Option<Shard>,
}

impl<'a> TilesToRun<'a> {
    /// Every tile of every frame.
    pub fn every(choice: TileChoice) -> Self {
        Self {
            choice,
            best: None,
            shard: None,
        }
    }

    /// The tiles that show a patch among its best views.
    pub fn best(best: &'a BestViews) -> Self {
        Self {
            choice: TileChoice::BestViews,
            best: Some(best),
            shard: None,
        }
    }

    /// Words for the choice: "the best 2 views of each patch".
    pub fn words(&self) -> String {
        match (self.choice, self.best) {
            (TileChoice::BestViews, Some(best)) => format!(
                "the best {} views of each patch of the map",
                best.views_per_patch
            ),
            (TileChoice::NoMap, _) => "every tile (no map to choose by)".into(),
            _ => "every tile".into(),
        }
    }
}

/// A frame and the windows of it to run.
pub(crate) struct FrameWork<'a> {
    pub(crate) frame: &'a Frame,
    pub(crate) windows: Vec<Window>,
}

/// Every frame's windows to run, and the skipped ones' reasons.
pub(crate) struct Chosen<'a> {
    pub(crate) work: Vec<FrameWork<'a>>,
    /// Frames in the share (all of them without one).
    pub(crate) frames: u64,
    pub(crate) skipped: Counts<TileSkip>,
}

impl Chosen<'_> {
    pub(crate) fn tiles(&self) -> u64 {
        self.work.iter().map(|w| w.windows.len() as u64).sum()
    }
}

/// The windows of `frames` to run by `tiles` (its share only).
pub(crate) fn choose<'a>(
    frames: &[&'a Frame],
    feed: Feed,
    options: &DetectOptions,
    tiles: TilesToRun<'_>,
) -> Chosen<'a> {
    let mut per_frame: Vec<(FrameWork<'a>, Counts<TileSkip>)> = frames
        .iter()
        .map(|frame| {
            let mut skipped = Counts::default();
            let all = frame_windows(frame, feed, options);
            let windows = match tiles.best {
                Some(best) => among_best(frame.index, all, best, &mut skipped),
                None => all,
            };
            (FrameWork { frame, windows }, skipped)
        })
        .collect();
    if let Some(shard) = tiles.shard {
        let work: Vec<u64> = per_frame
            .iter()
            .map(|(w, _)| w.windows.len() as u64)
            .collect();
        let mine = shares(&work, shard.count);
        per_frame = per_frame
            .into_iter()
            .zip(mine)
            .filter(|(_, s)| *s + 1 == shard.index)
            .map(|(w, _)| w)
            .collect();
    }
    let mut skipped = Counts::default();
    for (_, s) in &per_frame {
        skipped.add_all(s);
    }
    Chosen {
        frames: per_frame.len() as u64,
        work: per_frame
            .into_iter()
            .map(|(w, _)| w)
            .filter(|w| !w.windows.is_empty())
            .collect(),
        skipped,
    }
}

/// Every window of `frame` at its recorded size (the whole frame alone
/// when the size is not known).
pub(crate) fn frame_windows(frame: &Frame, feed: Feed, options: &DetectOptions) -> Vec<Window> {
    let (w, h) = (frame.width.unwrap_or(0), frame.height.unwrap_or(0));
    windows(
        w,
        h,
        feed.tile(options, w, h),
        options.settings.tile_overlap,
    )
}

/// The windows of frame `frame` (`all`: the whole frame first, then its
/// tiles) to run: an untiled frame whole, a tiled one's tile showing most
/// of each patch the frame is among the best views of; the rest counted
/// in `skipped` by why.
fn among_best(
    frame: u32,
    all: Vec<Window>,
    best: &BestViews,
    skipped: &mut Counts<TileSkip>,
) -> Vec<Window> {
    // Size unknown (0): the whole frame, wherever its boxes are.
    let extent = |pixels: u32| match pixels {
        0 => f32::MAX,
        n => n as f32,
    };
    let whole = BoxXyxy {
        x0: 0.0,
        y0: 0.0,
        x1: extent(all[0].width),
        y1: extent(all[0].height),
    };
    if let Some(why) = best.skip(frame, &whole) {
        skipped.add_many(why, all.len() as u64);
        return Vec::new();
    }
    if all.len() == 1 {
        return all;
    }
    let tiles = &all[1..];
    let mut chosen = vec![false; tiles.len()];
    for patch in best.best_boxes(frame) {
        let shown = |t: &Window| {
            let w = (patch.x1.min((t.x + t.width) as f32) - patch.x0.max(t.x as f32)).max(0.0);
            let h = (patch.y1.min((t.y + t.height) as f32) - patch.y0.max(t.y as f32)).max(0.0);
            w * h
        };
        // The first of the tiles showing most of it (tiles overlap: the
        // patch is often whole in one).
        let most = tiles
            .iter()
            .enumerate()
            .fold((None, 0.0f32), |(at, area), (i, t)| {
                let a = shown(t);
                if a > area { (Some(i), a) } else { (at, area) }
            });
        if let (Some(i), _) = most {
            chosen[i] = true;
        }
    }
    // Not the whole frame: shrunk, it would find the cracks of the tiles
    // skipped coarsely, and their widths and places with them.
    skipped.add(TileSkip::NotAmongBest);
    let mut run = Vec::new();
    for (tile, chosen) in tiles.iter().zip(chosen) {
        if chosen {
            run.push(*tile);
        } else {
            skipped.add(TileSkip::NotAmongBest);
        }
    }
    run
}

/// Which of `count` shares (from 0) each frame falls in, given the tiles
/// each runs: runs of frames, each holding about a `count`th of the tiles
/// (by the middle of each frame's own tiles), in frame order.
pub(crate) fn shares(tiles: &[u64], count: u32) -> Vec<u32> {
    let total: u64 = tiles.iter().sum();
    let mut before = 0u64;
    tiles
        .iter()
        .enumerate()
        .map(|(i, &t)| {
            let share = if total == 0 {
                // Nothing to run anywhere: frames evenly, for their counts.
                (i as u64 * u64::from(count) / tiles.len().max(1) as u64) as u32
            } else {
                // Twice the middle over twice the total: integers only.
                ((2 * before + t) * u64::from(count) / (2 * total)) as u32
            };
            before += t;
            share.min(count - 1)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use postflight_core::best_views::FrameViews;

    #[test]
    fn each_best_patch_runs_the_tile_showing_most_of_it() {
        // 1000 x 600 in 400 px tiles overlapping by a fifth: x at 0, 320,
        // 600; y at 0, 200.
        let all = windows(1000, 600, Some(400), 0.2);
        let mut best = BestViews::default();
        let b = |x0: f32, y0: f32, x1: f32, y1: f32| BoxXyxy { x0, y0, x1, y1 };
        best.frames.insert(
            7,
            FrameViews {
                patches_seen: 9,
                // Whole in the first tile and in the second: the first;
                // mostly in the last column's lower tile.
                best: vec![b(330.0, 50.0, 390.0, 100.0), b(700.0, 450.0, 980.0, 590.0)],
            },
        );
        let mut skipped = Counts::default();
        let run = among_best(7, all.clone(), &best, &mut skipped);
        let at: Vec<(i32, u32, u32)> = run.iter().map(|w| (w.tile, w.x, w.y)).collect();
        assert_eq!(at, [(0, 0, 0), (5, 600, 200)]);
        assert_eq!(skipped.get(TileSkip::NotAmongBest), all.len() as u64 - 2);
        // A frame with a pose seeing nothing, and one without a pose.
        best.frames.insert(8, FrameViews::default());
        let mut skipped = Counts::default();
        assert!(among_best(8, all.clone(), &best, &mut skipped).is_empty());
        assert!(among_best(9, all.clone(), &best, &mut skipped).is_empty());
        assert_eq!(skipped.get(TileSkip::NoSurface), all.len() as u64);
        assert_eq!(skipped.get(TileSkip::NoPose), all.len() as u64);
    }

    #[test]
    fn shares_hold_even_tiles_in_runs_of_frames() {
        // One heavy frame among light ones: the shares balance tiles.
        let tiles = [10, 10, 10, 10, 100, 10, 10, 10, 10, 0];
        let s = shares(&tiles, 4);
        assert!(s.windows(2).all(|p| p[0] <= p[1]), "{s:?}");
        let per: Vec<u64> = (0..4)
            .map(|k| {
                tiles
                    .iter()
                    .zip(&s)
                    .filter(|(_, x)| **x == k)
                    .map(|(t, _)| t)
                    .sum()
            })
            .collect();
        assert_eq!(per.iter().sum::<u64>(), 180);
        assert!(per.iter().all(|&p| p <= 100), "{per:?}");
        assert_eq!(s[4], 2, "the heavy frame is a share of its own: {s:?}");
        // More shares than frames: some are empty, none out of range.
        assert!(shares(&[5, 5], 4).iter().all(|&x| x < 4));
        assert_eq!(shares(&[0, 0, 0, 0], 2), [0, 0, 1, 1]);
    }
}
