//! The six sides of a voxel, named as inspectors and the tables name them
//! (`+x`, `-z`, ...): the axis and direction of the side's outward normal.

use std::fmt;

use nalgebra::Vector3;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::voxel::VoxelIndex;

/// A side of a voxel (its face on that side).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum FaceSide {
    PosX,
    NegX,
    PosY,
    NegY,
    PosZ,
    NegZ,
}

impl FaceSide {
    /// Every side, in the order of [`VoxelIndex::face_neighbours`].
    pub const ALL: [Self; 6] = [
        Self::PosX,
        Self::NegX,
        Self::PosY,
        Self::NegY,
        Self::PosZ,
        Self::NegZ,
    ];

    /// The side whose outward normal is `sign` along `axis` (0, 1, 2).
    pub fn from_axis(axis: usize, positive: bool) -> Self {
        Self::ALL[2 * axis + usize::from(!positive)]
    }

    /// The axis-aligned side whose outward normal is closest to `normal`.
    pub fn nearest(normal: &Vector3<f64>) -> Self {
        let axis = normal.iamax();
        Self::from_axis(axis, normal[axis] >= 0.0)
    }

    /// `+x`, `-y`, ...
    pub fn name(self) -> &'static str {
        ["+x", "-x", "+y", "-y", "+z", "-z"][self as usize]
    }

    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|s| s.name() == name)
    }

    /// Whether the outward normal points along its axis (`+x`, not `-x`).
    pub fn is_positive(self) -> bool {
        matches!(self, Self::PosX | Self::PosY | Self::PosZ)
    }

    /// The axis (0, 1, 2) the side faces along.
    pub fn axis(self) -> usize {
        self as usize / 2
    }

    /// Outward unit normal, in voxel steps.
    pub fn step(self) -> Vector3<i32> {
        let mut step = Vector3::zeros();
        step[self.axis()] = if self.is_positive() { 1 } else { -1 };
        step
    }

    /// Outward unit normal.
    pub fn normal(self) -> Vector3<f64> {
        self.step().map(f64::from)
    }

    /// The voxel on this side of `v`.
    pub fn neighbour(self, v: VoxelIndex) -> VoxelIndex {
        VoxelIndex((Vector3::from(v.0) + self.step()).into())
    }
}

impl crate::table::Named for FaceSide {
    const ALL: &'static [Self] = &Self::ALL;
    fn name(self) -> &'static str {
        self.name()
    }
}

impl fmt::Display for FaceSide {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl PartialEq<&str> for FaceSide {
    fn eq(&self, name: &&str) -> bool {
        self.name() == *name
    }
}

/// Written as its name, `"+x"`.
impl Serialize for FaceSide {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl<'de> Deserialize<'de> for FaceSide {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let name = String::deserialize(d)?;
        Self::parse(&name).ok_or_else(|| {
            serde::de::Error::custom(format!("{name:?} is not a voxel side (+x, -x, ... -z)"))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sides_agree_with_the_face_neighbours_and_their_names() {
        let v = VoxelIndex([3, -2, 7]);
        for (side, n) in FaceSide::ALL.into_iter().zip(v.face_neighbours()) {
            assert_eq!(side.neighbour(v), n);
            assert_eq!(FaceSide::parse(side.name()), Some(side));
            assert_eq!(FaceSide::nearest(&side.normal()), side);
            assert_eq!(
                FaceSide::from_axis(side.axis(), side.step().sum() > 0),
                side
            );
        }
        assert_eq!(FaceSide::nearest(&Vector3::new(0.2, -0.9, 0.3)), "-y");
        assert_eq!(serde_json::to_string(&FaceSide::NegZ).unwrap(), "\"-z\"");
    }
}
