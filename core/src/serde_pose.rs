//! JSON form of a pose: `{"translation": [x, y, z], "rotation_xyzw": [x, y, z, w]}`,
//! the field order ROS users read.

use nalgebra::Isometry3;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::pose::{from_parts_xyzw, quaternion_xyzw};

/// A pose as JSON writes it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PoseJson {
    pub translation: [f64; 3],
    pub rotation_xyzw: [f64; 4],
}

impl From<&Isometry3<f64>> for PoseJson {
    fn from(p: &Isometry3<f64>) -> Self {
        let t = p.translation.vector;
        Self {
            translation: [t.x, t.y, t.z],
            rotation_xyzw: quaternion_xyzw(p),
        }
    }
}

fn to_pose<E: serde::de::Error>(j: PoseJson) -> Result<Isometry3<f64>, E> {
    from_parts_xyzw(j.translation, j.rotation_xyzw)
        .ok_or_else(|| E::custom("pose rotation is not a valid quaternion"))
}

pub fn serialize<S: Serializer>(p: &Isometry3<f64>, s: S) -> Result<S::Ok, S::Error> {
    PoseJson::from(p).serialize(s)
}

pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Isometry3<f64>, D::Error> {
    to_pose(PoseJson::deserialize(d)?)
}

pub mod option {
    use super::*;

    pub fn serialize<S: Serializer>(p: &Option<Isometry3<f64>>, s: S) -> Result<S::Ok, S::Error> {
        p.as_ref().map(PoseJson::from).serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(
        d: D,
    ) -> Result<Option<Isometry3<f64>>, D::Error> {
        Option::<PoseJson>::deserialize(d)?.map(to_pose).transpose()
    }
}
