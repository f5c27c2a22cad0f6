//! What a real structure's surface shows besides cracks, and a crack
//! detector must not report: formwork joints (thin, dark and straight),
//! stains, rust streaks and the edges of shadows. Off by default; with them
//! on, a detector's precision can be measured against `truth.json`.

use nalgebra::{Point3, Vector3};
use serde::Serialize;

use crate::crack::FaceWalk;
use crate::render::overlap;
use crate::rng::Rng;
use crate::scene::{FacePicker, Scene};

/// What a mark on the surface is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum DistractorKind {
    /// A formwork panel joint: a straight, thin, dark groove across a face.
    Joint,
    /// A dark, soft-edged water or efflorescence stain.
    Stain,
    /// An orange-brown streak running down from a rusting fixing.
    RustStreak,
    /// The straight edge of another member's shadow.
    ShadowEdge,
}

/// One mark on one face.
#[derive(Debug, Clone)]
pub struct Distractor {
    pub kind: DistractorKind,
    /// A line along the face: a joint's ends, a streak's top and bottom, a
    /// shadow's edge; a stain's centre twice.
    pub line: [Point3<f64>; 2],
    /// A joint's or streak's width, a stain's diameter, the depth of a
    /// shadow beyond its edge; metres.
    pub width: f64,
    /// Outward normal of the face.
    pub normal: Vector3<f64>,
    pub triangle: u32,
}

/// How many of each kind a structure gets.
const COUNTS: [(DistractorKind, usize); 4] = [
    (DistractorKind::Joint, 14),
    (DistractorKind::Stain, 10),
    (DistractorKind::RustStreak, 8),
    (DistractorKind::ShadowEdge, 6),
];

/// Every mark of a scene.
#[derive(Debug, Clone, Default)]
pub struct Distractors(pub Vec<Distractor>);

impl Distractors {
    /// Marks drawn on the structure's larger faces.
    pub fn generate(scene: &Scene, rng: &mut Rng) -> Self {
        let faces = FacePicker::new(scene, 0.5);
        let mut marks = Vec::new();
        for (kind, count) in COUNTS {
            let mut attempts = 0;
            let mut made = 0;
            while made < count && attempts < count * 20 {
                attempts += 1;
                let Some(face) = faces.pick(rng) else {
                    break;
                };
                if let Some(mark) = place(scene, face, kind, rng) {
                    marks.push(mark);
                    made += 1;
                }
            }
        }
        Self(marks)
    }

    /// Each colour channel's factor at the surface point `p`, for a pixel
    /// spanning `pixel` metres there.
    pub fn tint(&self, p: &Point3<f64>, pixel: f64) -> [f64; 3] {
        let mut tint = [1.0; 3];
        for m in &self.0 {
            if (p - m.line[0]).dot(&m.normal).abs() > 0.02 {
                continue;
            }
            let (a, b) = (m.line[0], m.line[1]);
            let ab = b - a;
            let len = ab.norm();
            let along = if len > 1e-9 {
                ab / len
            } else {
                Vector3::zeros()
            };
            let s = (p - a).dot(&along);
            let across = (p - a) - along * s;
            let d = across.norm();
            let f = match m.kind {
                DistractorKind::Joint if (0.0..=len).contains(&s) => {
                    let share = overlap(d, pixel, m.width);
                    let dark = 1.0 - 0.5 * share;
                    [dark; 3]
                }
                DistractorKind::Stain => {
                    let r = m.width / 2.0;
                    let t = smooth(((r - (p - a).norm()) / (0.35 * r)).clamp(0.0, 1.0));
                    [1.0 - 0.28 * t, 1.0 - 0.3 * t, 1.0 - 0.34 * t]
                }
                DistractorKind::RustStreak if (0.0..=len).contains(&s) => {
                    // Widest and strongest at the fixing, fading downwards.
                    let fade = 1.0 - s / len;
                    let half = m.width * (0.5 + 0.5 * fade) / 2.0;
                    let t = fade * smooth(((half - d) / (0.4 * half)).clamp(0.0, 1.0));
                    [1.0 - 0.15 * t, 1.0 - 0.45 * t, 1.0 - 0.65 * t]
                }
                DistractorKind::ShadowEdge if (0.0..=len).contains(&s) => {
                    // The shadow lies on one side of the edge, `width` deep.
                    let side = m.normal.cross(&along);
                    let depth = (p - a).dot(&side);
                    let t = smooth(((depth + 0.01) / 0.02).clamp(0.0, 1.0))
                        * f64::from(u8::from(depth < m.width));
                    [1.0 - 0.45 * t; 3]
                }
                _ => [1.0; 3],
            };
            for c in 0..3 {
                tint[c] *= f[c];
            }
        }
        tint
    }
}

fn smooth(t: f64) -> f64 {
    t * t * (3.0 - 2.0 * t)
}

/// A mark of `kind` on the face of `triangle`, or `None` where it does not
/// fit.
fn place(scene: &Scene, triangle: u32, kind: DistractorKind, rng: &mut Rng) -> Option<Distractor> {
    let [a, b, c] = scene.triangles[triangle as usize];
    let face = FaceWalk::new(scene, triangle);
    let (mut s, mut t) = (rng.uniform(), rng.uniform());
    if s + t > 1.0 {
        (s, t) = (1.0 - s, 1.0 - t);
    }
    let at = a + (b - a) * s + (c - a) * t;
    // Down the face, where it is not level; else along it.
    let down = {
        let d = -Vector3::z() + face.normal * face.normal.z;
        if d.norm() > 0.3 {
            d.normalize()
        } else {
            face.u
        }
    };
    let level = face.normal.cross(&down).normalize();
    // How far from `at` the face goes on along `dir`, up to `max` metres.
    let reach = |dir: &Vector3<f64>, max: f64| {
        let mut r = 0.0;
        while r < max && face.on_face(&(at + dir * (r + 0.02))) {
            r += 0.02;
        }
        r
    };
    let (line, width) = match kind {
        DistractorKind::Joint => {
            // Panels are poured in lifts: joints run level, or plumb between panels.
            let dir = if rng.uniform() < 0.6 { level } else { down };
            let (ahead, behind) = (reach(&dir, 30.0), reach(&-dir, 30.0));
            (
                [at - dir * behind, at + dir * ahead],
                rng.range(0.003, 0.007),
            )
        }
        DistractorKind::Stain => ([at, at], rng.range(0.3, 1.0)),
        DistractorKind::RustStreak => {
            let length = reach(&down, rng.range(0.4, 1.5));
            ([at, at + down * length], rng.range(0.02, 0.06))
        }
        DistractorKind::ShadowEdge => {
            let heading = rng.range(0.0, std::f64::consts::PI);
            let dir = face.u * heading.cos() + face.v * heading.sin();
            let (ahead, behind) = (reach(&dir, 3.0), reach(&-dir, 3.0));
            ([at - dir * behind, at + dir * ahead], rng.range(0.3, 1.0))
        }
    };
    let long_enough = matches!(kind, DistractorKind::Stain) || (line[1] - line[0]).norm() > 0.3;
    long_enough.then_some(Distractor {
        kind,
        line,
        width,
        normal: face.normal,
        triangle,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn marks_lie_on_the_structure_and_change_its_look_where_they_are() {
        let scene = Scene::girder_bridge();
        let marks = Distractors::generate(&scene, &mut Rng::new(3));
        for (kind, count) in COUNTS {
            let n = marks.0.iter().filter(|m| m.kind == kind).count();
            assert!(n * 2 >= count, "{n} of {count} {kind:?}");
        }
        for m in &marks.0 {
            for p in m.line {
                let hit = scene.cast(&(p + m.normal * 0.2), &-m.normal, 1.0).unwrap();
                assert!(
                    (hit.distance - 0.2).abs() < 1e-3,
                    "{:?} off its face",
                    m.kind
                );
            }
        }
        let joint = marks
            .0
            .iter()
            .find(|m| m.kind == DistractorKind::Joint)
            .unwrap();
        let mid = Point3::from((joint.line[0].coords + joint.line[1].coords) / 2.0);
        assert!(marks.tint(&mid, 0.002)[0] < 0.6);
        assert_eq!(marks.tint(&(mid + joint.normal * 2.0), 0.002), [1.0; 3]);
        let streak = marks
            .0
            .iter()
            .find(|m| m.kind == DistractorKind::RustStreak)
            .unwrap();
        let top = marks.tint(
            &(streak.line[0] + (streak.line[1] - streak.line[0]) * 0.05),
            0.002,
        );
        assert!(top[2] < top[0] - 0.3, "rust is orange: {top:?}");
    }
}
