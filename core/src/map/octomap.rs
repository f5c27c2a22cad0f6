//! OctoMap occupancy trees, as `octomap_saver` and the OctoMap library
//! write them: `.bt` (binary: each leaf occupied or free) and `.ot` (full:
//! each node's log-odds). The occupied leaves become points at their voxel
//! centres, so the map voxelises on the tree's own grid: a leaf of the
//! finest level is one voxel, a leaf pruned higher up is every voxel it
//! stands for.
//!
//! Keys follow OctoMap: 16 levels, voxel key `k` spanning
//! `[(k - 32768) * res, (k - 32767) * res)` on each axis, child `i` of a
//! node offset by `i & 1` in x, `i & 2` in y and `i & 4` in z.

use nalgebra::Point3;

/// Levels below the root; a leaf at this depth is one voxel.
const TREE_DEPTH: u32 = 16;
/// The key of the voxel whose low corner is the world origin.
const KEY_CENTRE: i64 = 1 << (TREE_DEPTH - 1);
/// Most voxels a map may expand to (pruned leaves stand for many).
const MAX_VOXELS: u64 = 50_000_000;

/// Which of OctoMap's two tree files.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// `.bt`: `writeBinary`, two bits per child.
    Binary,
    /// `.ot`: `write`, a float and a child mask per node.
    Full,
}

/// An occupied leaf: the low key corner and the depth it was pruned at.
struct Leaf {
    key: [u32; 3],
    depth: u32,
}

/// An occupancy tree read from its file.
#[derive(Debug, Clone)]
pub struct OctoMap {
    /// Edge of the finest voxels, metres.
    pub resolution: f64,
    /// The centre of every occupied voxel.
    pub points: Vec<Point3<f64>>,
    /// Occupied leaves by depth (16: one voxel; less: pruned).
    pub leaves_by_depth: std::collections::BTreeMap<u32, usize>,
}

/// Read a tree file.
pub fn parse(bytes: &[u8], format: Format) -> Result<OctoMap, String> {
    let (resolution, data) = header(bytes, format)?;
    let mut reader = Reader { data, pos: 0 };
    let mut leaves = Vec::new();
    // An empty tree writes no nodes.
    if !data.is_empty() {
        let root = [0u32; 3];
        match format {
            Format::Binary => reader.binary_children(root, 0, &mut leaves)?,
            Format::Full => reader.full_node(root, 0, &mut leaves)?,
        }
    }
    let mut leaves_by_depth = std::collections::BTreeMap::new();
    for leaf in &leaves {
        *leaves_by_depth.entry(leaf.depth).or_insert(0) += 1;
    }
    Ok(OctoMap {
        resolution,
        points: centres(&leaves, resolution)?,
        leaves_by_depth,
    })
}

/// The text header up to its `data` line: the resolution, and the bytes after.
fn header(bytes: &[u8], format: Format) -> Result<(f64, &[u8]), String> {
    let (first, saver, extension) = match format {
        Format::Binary => ("# Octomap OcTree binary file", "the default", ".bt"),
        Format::Full => ("# Octomap OcTree file", "-f", ".ot"),
    };
    if !bytes.starts_with(first.as_bytes()) {
        return Err(format!(
            "it does not start with {first:?}; save the map with octomap_saver ({saver} for a {extension})"
        ));
    }
    let (mut id, mut resolution) = (None, None);
    let mut pos = 0;
    for line in bytes.split(|&b| b == b'\n') {
        pos += line.len() + 1;
        let text = String::from_utf8_lossy(line);
        let text = text.trim();
        if text == "data" {
            let id = id.ok_or("the header has no `id` line")?;
            if id != "OcTree" {
                return Err(format!(
                    "it holds a {id}; postflight reads OcTree maps (occupancy only)"
                ));
            }
            let resolution: f64 = resolution.ok_or("the header has no `res` line")?;
            if !(resolution.is_finite() && resolution > 0.0) {
                return Err(format!("resolution {resolution} is not a positive length"));
            }
            return Ok((resolution, bytes.get(pos..).unwrap_or_default()));
        }
        if text.starts_with('#') || text.is_empty() {
            continue;
        }
        match text.split_once(' ') {
            Some(("id", v)) => id = Some(v.trim().to_string()),
            Some(("res", v)) => {
                resolution = Some(
                    v.trim()
                        .parse()
                        .map_err(|_| format!("res {v:?} is not a number"))?,
                )
            }
            Some(("size", _)) => {}
            _ => return Err(format!("unexpected header line {text:?}")),
        }
        if pos > 4096 {
            break;
        }
    }
    Err("the header has no `data` line".into())
}

struct Reader<'a> {
    data: &'a [u8],
    pos: usize,
}

impl Reader<'_> {
    fn byte(&mut self) -> Result<u8, String> {
        let b = *self
            .data
            .get(self.pos)
            .ok_or_else(|| format!("the tree data ends early, at byte {} of it", self.pos))?;
        self.pos += 1;
        Ok(b)
    }

    /// A node of a `.bt`: two bytes of child states, then each inner
    /// child's own node.
    fn binary_children(
        &mut self,
        key: [u32; 3],
        depth: u32,
        leaves: &mut Vec<Leaf>,
    ) -> Result<(), String> {
        if depth >= TREE_DEPTH {
            return Err(too_deep());
        }
        let bits = u16::from(self.byte()?) | (u16::from(self.byte()?) << 8);
        // Per child, low bit alone: free leaf; high bit alone: occupied
        // leaf; both: inner node, whose own node follows; neither: unknown.
        let state = |i: u32| (bits >> (2 * i)) & 0b11;
        for i in (0..8).filter(|&i| state(i) == 0b10) {
            leaves.push(Leaf {
                key: child_key(key, depth, i),
                depth: depth + 1,
            });
        }
        for i in (0..8).filter(|&i| state(i) == 0b11) {
            self.binary_children(child_key(key, depth, i), depth + 1, leaves)?;
        }
        Ok(())
    }

    /// A node of an `.ot`: its log-odds, a mask of existing children, then
    /// each child; a node without children is a leaf.
    fn full_node(
        &mut self,
        key: [u32; 3],
        depth: u32,
        leaves: &mut Vec<Leaf>,
    ) -> Result<(), String> {
        let log_odds = f32::from_le_bytes([self.byte()?, self.byte()?, self.byte()?, self.byte()?]);
        let children = self.byte()?;
        if children == 0 {
            // OctoMap's default occupancy threshold: probability 0.5.
            if log_odds > 0.0 && depth > 0 {
                leaves.push(Leaf { key, depth });
            }
            return Ok(());
        }
        // Only inner nodes recurse, so no node lies deeper than this.
        if depth == TREE_DEPTH {
            return Err(too_deep());
        }
        for i in 0..8 {
            if children & (1 << i) != 0 {
                self.full_node(child_key(key, depth, i), depth + 1, leaves)?;
            }
        }
        Ok(())
    }
}

fn too_deep() -> String {
    format!("the tree is deeper than OctoMap's {TREE_DEPTH} levels")
}

/// The low key corner of child `i` of the node at `key`, `depth`.
fn child_key(key: [u32; 3], depth: u32, i: u32) -> [u32; 3] {
    let half = 1u32 << (TREE_DEPTH - depth - 1);
    [
        key[0] + if i & 1 != 0 { half } else { 0 },
        key[1] + if i & 2 != 0 { half } else { 0 },
        key[2] + if i & 4 != 0 { half } else { 0 },
    ]
}

/// Every voxel centre the occupied leaves stand for.
fn centres(leaves: &[Leaf], resolution: f64) -> Result<Vec<Point3<f64>>, String> {
    let voxels = leaves.iter().fold(0u64, |n, l| {
        n.saturating_add(1u64 << (3 * (TREE_DEPTH - l.depth)))
    });
    if voxels > MAX_VOXELS {
        return Err(format!(
            "its occupied space is {voxels} voxels at its resolution, more than the {MAX_VOXELS} a map may hold; crop it to the structure (octomap's edit_octree -bbx)"
        ));
    }
    let centre = |k: u32| (i64::from(k) - KEY_CENTRE) as f64 * resolution + 0.5 * resolution;
    let mut points = Vec::with_capacity(voxels as usize);
    for leaf in leaves {
        let side = 1u32 << (TREE_DEPTH - leaf.depth);
        for dz in 0..side {
            for dy in 0..side {
                for dx in 0..side {
                    points.push(Point3::new(
                        centre(leaf.key[0] + dx),
                        centre(leaf.key[1] + dy),
                        centre(leaf.key[2] + dz),
                    ));
                }
            }
        }
    }
    Ok(points)
}
