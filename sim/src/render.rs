//! Rendering a frame: one ray per pixel through the lens model into the
//! scene, concrete shading with the cracks drawn at their true width (so a
//! crack fades with distance) and spalls' broken surfaces where the rays
//! fall into them, the lens's point-spread function, the
//! sensor's noise, then motion blur along the image motion.

use image::RgbImage;
use nalgebra::{Isometry3, Point2, Point3, Vector3};
use postflight_core::Intrinsics;
use rayon::prelude::*;

use crate::crack::Cracks;
use crate::distractor::Distractors;
use crate::rng::hash3;
use crate::scene::{Class, Scene};
use crate::spall::{SpallHit, Spalls};

/// Farthest distance rendered, metres.
const MAX_RANGE: f64 = 300.0;

/// Unit rays of every pixel centre in the optical frame, distortion undone.
pub struct RayTable {
    pub width: u32,
    pub height: u32,
    rays: Vec<Vector3<f64>>,
    /// Angle one pixel subtends at the image centre, radians.
    pub pixel_angle: f64,
}

impl RayTable {
    pub fn new(k: &Intrinsics) -> Self {
        let rays = (0..k.height)
            .into_par_iter()
            .flat_map_iter(|y| {
                (0..k.width)
                    .map(move |x| k.ray(&Point2::new(f64::from(x) + 0.5, f64::from(y) + 0.5)))
            })
            .collect();
        Self {
            width: k.width,
            height: k.height,
            rays,
            pixel_angle: 1.0 / k.fx,
        }
    }
}

/// How the structure's concrete looks at centimetre scale.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Surface {
    /// Blotches and fine grit, as the default flights have always shown.
    #[default]
    Smooth,
    /// Also aggregate, formwork board grain and weathering streaks: the
    /// texture structure-from-motion matches from frame to frame (on the
    /// smooth surface SIFT finds a few dozen keypoints a frame).
    Textured,
}

impl Surface {
    /// `Textured` when `textured`, else `Smooth` (the `--textured` flag).
    pub fn textured_if(textured: bool) -> Self {
        if textured {
            Self::Textured
        } else {
            Self::Smooth
        }
    }
}

/// Render the view of a camera at `camera` (`T_world_camera`, optical frame)
/// as a camera records it: the scene through the lens, spread by its
/// point-spread function (a Gaussian of `lens_blur_px`, one standard
/// deviation in pixels; 0 none), each pixel the light over its area (a
/// crack drawn by the share of the pixel it covers), then the sensor's
/// noise.
pub fn render(
    scene: &Scene,
    drawn: &Drawn<'_>,
    rays: &RayTable,
    camera: &Isometry3<f64>,
    frame: u32,
    surface: Surface,
    lens_blur_px: f64,
) -> RgbImage {
    let origin = Point3::from(camera.translation.vector);
    let (w, h) = (rays.width as usize, rays.height as usize);
    let mut light = vec![[0.0f64; 3]; w * h];
    light.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, px) in row.iter_mut().enumerate() {
            let dir = camera.rotation * rays.rays[y * w + x];
            let rgb = shade(scene, drawn, &origin, &dir, rays.pixel_angle, surface);
            *px = rgb;
        }
    });
    let light = lens_blur(light, w, h, lens_blur_px);
    let mut img = RgbImage::new(rays.width, rays.height);
    img.par_chunks_mut(w * 3).enumerate().for_each(|(y, row)| {
        for x in 0..w {
            // Sensor noise, fixed per pixel and frame so output is deterministic.
            let n = (hash3(x as i64, y as i64, i64::from(frame), 17) - 0.5) * 6.0;
            for c in 0..3 {
                row[x * 3 + c] = (light[y * w + x][c] + n).clamp(0.0, 255.0) as u8;
            }
        }
    });
    img
}

/// The lens's point-spread function sampled on the pixel grid: weights of
/// a Gaussian of `sigma_px` at -r..=r pixels (r = 3σ), summing to 1; one
/// weight of 1 without blur.
fn lens_weights(sigma_px: f64) -> Vec<f64> {
    if sigma_px <= 0.0 {
        return vec![1.0];
    }
    let r = (3.0 * sigma_px).ceil() as isize;
    let weights: Vec<f64> = (-r..=r)
        .map(|i| (-(i as f64).powi(2) / (2.0 * sigma_px * sigma_px)).exp())
        .collect();
    let total: f64 = weights.iter().sum();
    weights.into_iter().map(|w| w / total).collect()
}

/// How many pixels the lens spreads a thin line's darkness over: the
/// reciprocal of the share of its light that stays in the pixel it crosses
/// (1.51 px at σ = 0.6 px; 1 without blur).
pub fn lens_spread_px(sigma_px: f64) -> f64 {
    let weights = lens_weights(sigma_px);
    1.0 / weights[weights.len() / 2]
}

/// The lens's point-spread function: `light` (a `w` x `h` image) blurred
/// by a Gaussian of `sigma_px`, along rows then columns, the border
/// repeated.
fn lens_blur(light: Vec<[f64; 3]>, w: usize, h: usize, sigma_px: f64) -> Vec<[f64; 3]> {
    if sigma_px <= 0.0 {
        return light;
    }
    let weights = lens_weights(sigma_px);
    let r = (weights.len() / 2) as isize;
    let pass = |from: &[[f64; 3]], along_rows: bool| -> Vec<[f64; 3]> {
        let mut out = vec![[0.0f64; 3]; w * h];
        out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            for (x, px) in row.iter_mut().enumerate() {
                let mut acc = [0.0f64; 3];
                for (k, weight) in weights.iter().enumerate() {
                    let d = k as isize - r;
                    let (sx, sy) = if along_rows {
                        ((x as isize + d).clamp(0, w as isize - 1) as usize, y)
                    } else {
                        (x, (y as isize + d).clamp(0, h as isize - 1) as usize)
                    };
                    let v = from[sy * w + sx];
                    for c in 0..3 {
                        acc[c] += weight * v[c];
                    }
                }
                *px = acc;
            }
        });
        out
    };
    pass(&pass(&light, true), false)
}

/// What is drawn on the structure's surface: cracks, marks that are not
/// cracks, and spalls.
pub struct Drawn<'a> {
    pub cracks: &'a Cracks,
    pub marks: &'a Distractors,
    pub spalls: &'a Spalls,
}

fn shade(
    scene: &Scene,
    drawn: &Drawn<'_>,
    origin: &Point3<f64>,
    dir: &Vector3<f64>,
    pixel_angle: f64,
    surface: Surface,
) -> [f64; 3] {
    let Some(hit) = scene.cast(origin, dir, MAX_RANGE) else {
        // Sky: brighter towards the horizon.
        let up = dir.z.max(0.0);
        return [150.0 + 60.0 * (1.0 - up), 185.0 + 40.0 * (1.0 - up), 235.0];
    };
    let sun = Vector3::new(0.35, -0.25, 0.9).normalize();
    let infrastructure = scene.class(hit.triangle) == Class::Infrastructure;
    if let Some(broken) = drawn.spalls.hit(&hit.point, dir).filter(|_| infrastructure) {
        let light = 0.45 + 0.55 * broken.normal.dot(&sun).max(0.0);
        return broken_concrete(&broken).map(|c| c * light);
    }
    let light = 0.45 + 0.55 * hit.normal.dot(&sun).max(0.0);
    let p = hit.point;
    let (cracks, marks) = (drawn.cracks, drawn.marks);
    let base = match scene.class(hit.triangle) {
        Class::Infrastructure => {
            let g = match surface {
                Surface::Smooth => concrete(&p),
                Surface::Textured => concrete(&p) + texture(&p, &hit.normal),
            };
            let cos = hit.normal.dot(&-dir).abs().max(0.2);
            let pixel = hit.distance * pixel_angle;
            let crack = cracks.darkness(&p, dir, pixel / cos, pixel);
            let v = g * (1.0 - crack);
            let tint = marks.tint(&p, pixel);
            [v * tint[0], v * 0.98 * tint[1], v * 0.94 * tint[2]]
        }
        Class::Obstacle => {
            let n = 0.8 + 0.4 * value_noise(&p, 4.0, 3);
            [60.0 * n, 95.0 * n, 45.0 * n]
        }
        Class::Ground => {
            let n = 0.85 + 0.3 * value_noise(&p, 1.5, 5);
            [95.0 * n, 120.0 * n, 70.0 * n]
        }
    };
    base.map(|c| c * light)
}

/// The broken surface of a spall: rough concrete darker and warmer than
/// the weathered face (fresh fracture through aggregate and paste, the
/// sand's colour showing), a bar showing in it rust brown.
fn broken_concrete(hit: &SpallHit) -> [f64; 3] {
    let p = &hit.point;
    let rough = 0.75 + 0.5 * value_noise(p, 90.0, 31) + 0.2 * (value_noise(p, 300.0, 33) - 0.5);
    if hit.on_bar {
        return [128.0 * rough, 72.0 * rough, 40.0 * rough];
    }
    let g = 110.0 * rough;
    [g, g * 0.93, g * 0.80]
}

/// Share of a pixel `pixel` wide, centred `d` from a line's axis, that a
/// band `width` wide around the axis covers.
pub(crate) fn overlap(d: f64, pixel: f64, width: f64) -> f64 {
    let (lo, hi) = (d - pixel / 2.0, d + pixel / 2.0);
    ((hi.min(width / 2.0) - lo.max(-width / 2.0)) / pixel).clamp(0.0, 1.0)
}

/// Grey concrete: blotches at several scales plus fine aggregate.
fn concrete(p: &Point3<f64>) -> f64 {
    let blotch =
        0.5 * value_noise(p, 0.8, 1) + 0.3 * value_noise(p, 3.0, 2) + 0.2 * value_noise(p, 12.0, 4);
    let grit = hash3(
        (p.x * 400.0) as i64,
        (p.y * 400.0) as i64,
        (p.z * 400.0) as i64,
        9,
    );
    150.0 + 60.0 * (blotch - 0.5) + 14.0 * (grit - 0.5)
}

/// What textured concrete adds to [`concrete`], grey levels: aggregate
/// (pale pebbles a centimetre or two across: paler than the paste, as
/// limestone aggregate is, so a crack detector looking for dark lines
/// passes them by, and distinct, so structure-from-motion matches them),
/// each formwork board (15 cm, along
/// the face) a shade of its own, and broad weathering down the face.
fn texture(p: &Point3<f64>, normal: &Vector3<f64>) -> f64 {
    let smooth = |lo: f64, hi: f64, v: f64| {
        let t = ((v - lo) / (hi - lo)).clamp(0.0, 1.0);
        t * t * (3.0 - 2.0 * t)
    };
    let pebbles = value_noise(p, 55.0, 21);
    let aggregate = 32.0 * smooth(0.6, 0.7, pebbles) + 16.0 * smooth(0.3, 0.2, pebbles);
    // Boards run horizontally on walls, across the span under a deck.
    let across = if normal.z.abs() > 0.7 { p.x } else { p.z };
    let board = (across / 0.15).floor();
    let shade = 12.0 * (hash3(board as i64, 0, 0, 23) - 0.5);
    let weathering_at = Point3::new(p.x * 3.0, p.y * 3.0, p.z * 0.5);
    let weathering = -10.0 * value_noise(&weathering_at, 1.0, 25);
    aggregate + shade + weathering
}

/// Smooth 3D value noise in [0, 1] at `freq` cycles per metre.
fn value_noise(p: &Point3<f64>, freq: f64, salt: u64) -> f64 {
    let q = p.coords * freq;
    let (ix, iy, iz) = (q.x.floor(), q.y.floor(), q.z.floor());
    let f = |v: f64| v * v * (3.0 - 2.0 * v);
    let (fx, fy, fz) = (f(q.x - ix), f(q.y - iy), f(q.z - iz));
    let h = |dx: i64, dy: i64, dz: i64| hash3(ix as i64 + dx, iy as i64 + dy, iz as i64 + dz, salt);
    let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
    let x00 = lerp(h(0, 0, 0), h(1, 0, 0), fx);
    let x10 = lerp(h(0, 1, 0), h(1, 1, 0), fx);
    let x01 = lerp(h(0, 0, 1), h(1, 0, 1), fx);
    let x11 = lerp(h(0, 1, 1), h(1, 1, 1), fx);
    lerp(lerp(x00, x10, fy), lerp(x01, x11, fy), fz)
}

/// Average the image along the motion vector `(dx, dy)` pixels (the image
/// motion during the exposure), as a moving camera blurs.
pub fn motion_blur(img: RgbImage, dx: f64, dy: f64) -> RgbImage {
    let len = dx.hypot(dy);
    if len < 0.5 {
        return img;
    }
    let taps = len.ceil() as usize + 1;
    let (w, h) = (img.width() as i64, img.height() as i64);
    let mut out = RgbImage::new(img.width(), img.height());
    let src = img.as_raw();
    out.par_chunks_mut(w as usize * 3)
        .enumerate()
        .for_each(|(y, row)| {
            for x in 0..w {
                let mut acc = [0u32; 3];
                for k in 0..taps {
                    let s = k as f64 / (taps - 1) as f64 - 0.5;
                    let sx = (x as f64 + dx * s).round().clamp(0.0, (w - 1) as f64) as usize;
                    let sy = (y as f64 + dy * s).round().clamp(0.0, (h - 1) as f64) as usize;
                    let i = (sy * w as usize + sx) * 3;
                    for c in 0..3 {
                        acc[c] += u32::from(src[i + c]);
                    }
                }
                for c in 0..3 {
                    row[x as usize * 3 + c] = (acc[c] / taps as u32) as u8;
                }
            }
        });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_lens_spreads_a_line_and_keeps_its_light() {
        // A dark line one pixel wide down column 10 of a 21 x 5 image.
        let (w, h) = (21, 5);
        let light: Vec<[f64; 3]> = (0..w * h)
            .map(|i| if i % w == 10 { [0.0; 3] } else { [100.0; 3] })
            .collect();
        let blurred = lens_blur(light, w, h, 0.6);
        let row: Vec<f64> = (0..w).map(|x| blurred[2 * w + x][0]).collect();
        // The light it takes away is kept, spread over its neighbours.
        let taken: f64 = row.iter().map(|v| 100.0 - v).sum();
        assert!((taken - 100.0).abs() < 0.01, "{row:?}");
        assert!(row[10] > 30.0 && row[9] < 95.0 && row[11] < 95.0, "{row:?}");
        // The line keeps 1 / lens_spread_px of its darkness where it is.
        let kept = (100.0 - row[10]) / 100.0;
        assert!((kept * lens_spread_px(0.6) - 1.0).abs() < 1e-9, "{kept}");
        assert_eq!(lens_spread_px(0.0), 1.0);
        assert_eq!(lens_blur(vec![[7.0; 3]; 4], 2, 2, 0.0), vec![[7.0; 3]; 4]);
    }

    #[test]
    fn a_band_covers_the_share_of_a_pixel_it_overlaps() {
        assert_eq!(overlap(0.0, 1.0, 0.5), 0.5);
        assert_eq!(overlap(0.0, 1.0, 3.0), 1.0);
        assert_eq!(overlap(2.0, 1.0, 0.5), 0.0);
        assert!((overlap(0.5, 1.0, 1.0) - 0.5).abs() < 1e-12);
    }
}
