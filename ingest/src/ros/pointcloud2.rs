//! `sensor_msgs/msg/PointCloud2` to points: `x`, `y`, `z` as float32 or
//! float64 at any offset and point step, in either byte order.

use nalgebra::Point3;

use super::msg::PointCloud2;
use postflight_core::map::PointCloud;

const FLOAT32: u8 = 7;
const FLOAT64: u8 = 8;

pub fn decode(msg: &PointCloud2) -> Result<PointCloud, String> {
    let field = |name: &str| {
        msg.fields
            .iter()
            .find(|f| f.name == name)
            .ok_or(format!("PointCloud2 has no {name} field"))
            .and_then(|f| match f.datatype {
                FLOAT32 => Ok((f.offset as usize, 4)),
                FLOAT64 => Ok((f.offset as usize, 8)),
                other => Err(format!(
                    "PointCloud2 field {name} has datatype {other}; only FLOAT32 (7) and FLOAT64 (8) are supported"
                )),
            })
    };
    let xyz = [field("x")?, field("y")?, field("z")?];
    let step = msg.point_step as usize;
    let (width, height) = (msg.width as usize, msg.height as usize);
    let row_step = (msg.row_step as usize).max(width * step);
    if xyz.iter().any(|(off, size)| off + size > step) {
        return Err("PointCloud2 fields lie outside point_step".into());
    }
    if height > 0 && msg.data.len() < row_step * (height - 1) + width * step {
        return Err(format!(
            "PointCloud2 data has {} bytes, too few for {width}x{height} points of {step} bytes",
            msg.data.len()
        ));
    }
    let big = msg.is_bigendian;
    let read = |b: &[u8], (off, size): (usize, usize)| -> f64 {
        let b = &b[off..off + size];
        match (size, big) {
            (4, false) => f64::from(f32::from_le_bytes(b.try_into().unwrap())),
            (4, true) => f64::from(f32::from_be_bytes(b.try_into().unwrap())),
            (_, false) => f64::from_le_bytes(b.try_into().unwrap()),
            (_, true) => f64::from_be_bytes(b.try_into().unwrap()),
        }
    };
    let mut points = Vec::with_capacity(width * height);
    for row in 0..height {
        for col in 0..width {
            let p = &msg.data[row * row_step + col * step..];
            let point = Point3::new(read(p, xyz[0]), read(p, xyz[1]), read(p, xyz[2]));
            // Organised clouds mark missing returns with NaN.
            if point.iter().all(|v| v.is_finite()) {
                points.push(point);
            }
        }
    }
    Ok(PointCloud {
        frame_id: msg.header.frame_id.clone(),
        points,
        grid: None,
        mesh_spacing_m: None,
    })
}
