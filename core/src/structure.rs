//! The structure as inspectors name it: elements (deck, girders, piers, a
//! tower) and places on them in the field's words ("pier 2, east face,
//! 1.4 m above its base"). The `targets` crate finds the elements from
//! the target voxels; these are the types the tables and pages share.
//!
//! The map frame is taken as ROS's: x east, y north, z up (REP 103), so
//! faces are named by compass.

use std::collections::HashMap;
use std::fmt;

use nalgebra::{Point3, Vector2, Vector3};
use serde::{Deserialize, Serialize};

use crate::map::{VoxelGrid, VoxelIndex};

/// What an element is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ElementKind {
    Deck,
    Girder,
    Pier,
    Tower,
    /// Named by the user (a named target box), or not recognised.
    Part,
}

impl ElementKind {
    /// Whether places on it are measured along the span (deck, girders)
    /// rather than up from its base.
    pub fn runs_along_span(self) -> bool {
        matches!(self, Self::Deck | Self::Girder)
    }
}

/// One element of the structure.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Element {
    pub name: String,
    pub kind: ElementKind,
    /// Bottom of its lowest voxel, world z, metres.
    pub base_z_m: f64,
    /// Where it starts along the span axis (projection on [`Structure::axis`]), metres.
    pub start_m: f64,
    pub voxels: usize,
}

/// The elements of a structure and the axis it runs along.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Structure {
    /// Unit horizontal direction of the span (east-ish, or north for a
    /// north–south span).
    pub axis: [f64; 2],
    pub elements: Vec<Element>,
}

/// The major horizontal axis of `points` (their covariance's major
/// eigenvector), pointing east, or north when it runs north–south: the
/// direction a span, a wall or a cap runs along.
pub fn major_axis(points: &[Vector2<f64>]) -> Vector2<f64> {
    let n = points.len().max(1) as f64;
    let mean = points.iter().sum::<Vector2<f64>>() / n;
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in points {
        let d = p - mean;
        sxx += d.x * d.x;
        sxy += d.x * d.y;
        syy += d.y * d.y;
    }
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let axis = Vector2::new(angle.cos(), angle.sin());
    if axis.x < -1e-9 || (axis.x.abs() <= 1e-9 && axis.y < 0.0) {
        -axis
    } else {
        axis
    }
}

/// Which way a face looks, in the words used on site.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Facing {
    Top,
    Underside,
    /// A side, by the compass point it faces.
    Side(Compass),
}

/// The eight compass points, anticlockwise from east (map x).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Compass {
    East,
    NorthEast,
    North,
    NorthWest,
    West,
    SouthWest,
    South,
    SouthEast,
}

impl Compass {
    const ALL: [Self; 8] = [
        Self::East,
        Self::NorthEast,
        Self::North,
        Self::NorthWest,
        Self::West,
        Self::SouthWest,
        Self::South,
        Self::SouthEast,
    ];

    /// The compass point nearest horizontal direction `(x, y)`.
    pub fn of(x: f64, y: f64) -> Self {
        let eighths = (y.atan2(x) / std::f64::consts::FRAC_PI_4).round() as i32;
        Self::ALL[eighths.rem_euclid(8) as usize]
    }

    pub fn word(self) -> &'static str {
        match self {
            Self::East => "east",
            Self::NorthEast => "north-east",
            Self::North => "north",
            Self::NorthWest => "north-west",
            Self::West => "west",
            Self::SouthWest => "south-west",
            Self::South => "south",
            Self::SouthEast => "south-east",
        }
    }
}

impl Facing {
    /// Faces tilted less than 45 degrees from level are tops or undersides.
    pub fn of(normal: &Vector3<f64>) -> Self {
        let n = normal.normalize();
        if n.z >= std::f64::consts::FRAC_1_SQRT_2 {
            Self::Top
        } else if n.z <= -std::f64::consts::FRAC_1_SQRT_2 {
            Self::Underside
        } else {
            Self::Side(Compass::of(n.x, n.y))
        }
    }

    /// The face's name on an element of `kind`: a deck's underside is its soffit.
    pub fn word(self, kind: ElementKind) -> String {
        match (self, kind) {
            (Self::Top, _) => "top".into(),
            (Self::Underside, ElementKind::Deck) => "soffit".into(),
            (Self::Underside, _) => "underside".into(),
            (Self::Side(c), ElementKind::Deck) => format!("{} edge", c.word()),
            (Self::Side(c), _) => format!("{} face", c.word()),
        }
    }
}

/// A place on the structure.
#[derive(Debug, Clone, PartialEq)]
pub struct Place {
    pub element: String,
    /// The face's name on its element: `east face`, `soffit`, `top`.
    pub face: String,
    /// How far along or up the element, with what from:
    /// `1.4 m above its base`, `12.3 m from its west end`.
    pub offset: String,
}

impl fmt::Display for Place {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}, {}, {}", self.element, self.face, self.offset)
    }
}

impl Structure {
    fn axis(&self) -> Vector2<f64> {
        Vector2::new(self.axis[0], self.axis[1])
    }

    /// Where `point` (facing `normal`) is on element `element`.
    pub fn place(&self, element: usize, point: &Point3<f64>, normal: &Vector3<f64>) -> Place {
        let e = &self.elements[element];
        let offset = if e.kind.runs_along_span() {
            let along = self.axis().dot(&point.xy().coords) - e.start_m;
            let from = Compass::of(-self.axis[0], -self.axis[1]).word();
            format!("{along:.1} m from its {from} end")
        } else {
            format!("{:.1} m above its base", point.z - e.base_z_m)
        };
        Place {
            element: e.name.clone(),
            face: Facing::of(normal).word(e.kind),
            offset,
        }
    }
}

/// Finds the element of a point from the target voxels near it.
#[derive(Debug, Clone)]
pub struct ElementMap {
    pub structure: Structure,
    grid: VoxelGrid,
    element_of: HashMap<VoxelIndex, usize>,
}

/// How far from a target voxel a point may be and still be on it, voxels.
const REACH_VOXELS: i32 = 2;

impl ElementMap {
    pub fn new(
        structure: Structure,
        grid: VoxelGrid,
        voxels: impl IntoIterator<Item = (VoxelIndex, usize)>,
    ) -> Self {
        Self {
            structure,
            grid,
            element_of: voxels.into_iter().collect(),
        }
    }

    /// The element target voxel `v` is part of.
    pub fn element_of(&self, v: VoxelIndex) -> Option<&Element> {
        self.element_of
            .get(&v)
            .map(|&e| &self.structure.elements[e])
    }

    /// The element of the target voxel nearest `point` (within two voxels).
    pub fn element_at(&self, point: &Point3<f64>) -> Option<usize> {
        let at = self.grid.voxel_of(point);
        let r = REACH_VOXELS;
        let mut best: Option<(f64, usize)> = None;
        for dx in -r..=r {
            for dy in -r..=r {
                for dz in -r..=r {
                    let v = VoxelIndex([at.0[0] + dx, at.0[1] + dy, at.0[2] + dz]);
                    if let Some(&e) = self.element_of.get(&v) {
                        let d = (self.grid.center(v) - point).norm();
                        if best.is_none_or(|(bd, _)| d < bd) {
                            best = Some((d, e));
                        }
                    }
                }
            }
        }
        best.map(|(_, e)| e)
    }

    /// Where `point`, facing `normal`, is on the structure; `None` off it.
    pub fn place(&self, point: &Point3<f64>, normal: &Vector3<f64>) -> Option<Place> {
        self.element_at(point)
            .map(|e| self.structure.place(e, point, normal))
    }
}
