//! A serde deserializer for ROS 1 serialised messages, driven by the
//! message's [`Definition`]: little-endian values packed without padding,
//! strings and variable arrays prefixed by a `uint32` length.
//!
//! Fields are matched by name, so a struct that names fewer fields than the
//! recording carries still decodes (the rest are skipped without copying),
//! and a `time` reads as `{sec, nanosec}` like a ROS 2 `Time`. A fixed array
//! of N values also reads as nested tuples whose lengths multiply to N
//! (`float64[36]` as `[[f64; 6]; 6]`), the shape the ROS 2 structs use.

use serde::Deserialize;
use serde::de::value::{MapDeserializer, StrDeserializer};
use serde::de::{self, DeserializeSeed, IntoDeserializer, MapAccess, SeqAccess, Visitor};

use super::definition::{Definition, FieldType, MessageType, Primitive};

/// Why a ROS 1 message could not be decoded.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Ros1Error {
    #[error("the message ends inside field {field} (byte {at} of {len})")]
    Truncated {
        field: String,
        at: usize,
        len: usize,
    },
    #[error(
        "field {field} claims {count} elements, more than the {left} bytes left in the message hold"
    )]
    Length {
        field: String,
        count: u64,
        left: usize,
    },
    #[error("{0}")]
    Custom(String),
}

impl de::Error for Ros1Error {
    fn custom<T: std::fmt::Display>(msg: T) -> Self {
        Self::Custom(msg.to_string())
    }
}

/// Decode one message of `definition`'s root type from `data`.
pub fn decode<'de, T: Deserialize<'de>>(
    definition: &Definition,
    data: &'de [u8],
) -> Result<T, Ros1Error> {
    static ROOT: FieldType = FieldType::Message(0);
    let mut reader = Reader {
        definition,
        data,
        pos: 0,
        field: &definition.root().name,
    };
    T::deserialize(Value {
        reader: &mut reader,
        ty: &ROOT,
        group: 1,
    })
}

/// The bytes being read and where.
struct Reader<'a, 'de> {
    definition: &'a Definition,
    data: &'de [u8],
    pos: usize,
    /// The field being read, for errors.
    field: &'a str,
}

impl<'a, 'de> Reader<'a, 'de> {
    fn take(&mut self, n: usize) -> Result<&'de [u8], Ros1Error> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.data.len());
        let Some(end) = end else {
            return Err(Ros1Error::Truncated {
                field: self.field.to_string(),
                at: self.pos,
                len: self.data.len(),
            });
        };
        let bytes = &self.data[self.pos..end];
        self.pos = end;
        Ok(bytes)
    }

    fn array<const N: usize>(&mut self) -> Result<[u8; N], Ros1Error> {
        Ok(self.take(N)?.try_into().expect("take returns N bytes"))
    }

    fn u32(&mut self) -> Result<u32, Ros1Error> {
        Ok(u32::from_le_bytes(self.array()?))
    }

    /// A `uint32` element count, checked against the bytes left so a
    /// damaged length fails here instead of allocating or looping.
    fn count(&mut self, element: &FieldType) -> Result<usize, Ros1Error> {
        let count = self.u32()?;
        let least = self.definition.min_size(element).max(1) as u64;
        let left = self.data.len() - self.pos;
        if u64::from(count).saturating_mul(least) > left as u64 {
            return Err(Ros1Error::Length {
                field: self.field.to_string(),
                count: u64::from(count),
                left,
            });
        }
        Ok(count as usize)
    }

    fn skip(&mut self, ty: &FieldType, group: usize) -> Result<(), Ros1Error> {
        match ty {
            FieldType::Primitive(Primitive::String) => {
                for _ in 0..group {
                    let n = self.u32()? as usize;
                    self.take(n)?;
                }
            }
            FieldType::Primitive(p) => {
                self.take(p.size().saturating_mul(group))?;
            }
            FieldType::Message(i) => {
                let definition = self.definition;
                for field in &definition.types[*i].fields {
                    self.skip(&field.ty, 1)?;
                }
            }
            FieldType::Array { element, len } => {
                let n = match len {
                    Some(n) => *n,
                    None => self.count(element)?,
                };
                match **element {
                    FieldType::Primitive(p) if p != Primitive::String => {
                        self.take(p.size().saturating_mul(n))?;
                    }
                    _ => {
                        for _ in 0..n {
                            self.skip(element, 1)?;
                        }
                    }
                }
            }
        }
        Ok(())
    }
}

/// One value of type `ty` about to be read; `group` > 1 for a run of
/// primitives read as one tuple (see the module docs).
struct Value<'r, 'a, 'de> {
    reader: &'r mut Reader<'a, 'de>,
    ty: &'a FieldType,
    group: usize,
}

impl<'de> Value<'_, '_, 'de> {
    fn primitive<V: Visitor<'de>>(self, p: Primitive, visitor: V) -> Result<V::Value, Ros1Error> {
        let r = self.reader;
        match p {
            Primitive::Bool => visitor.visit_bool(r.array::<1>()?[0] != 0),
            Primitive::Int8 => visitor.visit_i8(i8::from_le_bytes(r.array()?)),
            Primitive::UInt8 => visitor.visit_u8(r.array::<1>()?[0]),
            Primitive::Int16 => visitor.visit_i16(i16::from_le_bytes(r.array()?)),
            Primitive::UInt16 => visitor.visit_u16(u16::from_le_bytes(r.array()?)),
            Primitive::Int32 => visitor.visit_i32(i32::from_le_bytes(r.array()?)),
            Primitive::UInt32 => visitor.visit_u32(r.u32()?),
            Primitive::Int64 => visitor.visit_i64(i64::from_le_bytes(r.array()?)),
            Primitive::UInt64 => visitor.visit_u64(u64::from_le_bytes(r.array()?)),
            Primitive::Float32 => visitor.visit_f32(f32::from_le_bytes(r.array()?)),
            Primitive::Float64 => visitor.visit_f64(f64::from_le_bytes(r.array()?)),
            Primitive::String => {
                let n = r.u32()? as usize;
                match std::str::from_utf8(r.take(n)?) {
                    Ok(s) => visitor.visit_borrowed_str(s),
                    Err(_) => Err(Ros1Error::Custom(format!(
                        "field {} is not UTF-8 text",
                        r.field
                    ))),
                }
            }
            Primitive::Time => {
                let (sec, nanosec) = (r.u32()?, r.u32()?);
                visitor.visit_map(MapDeserializer::new(
                    [("sec", sec), ("nanosec", nanosec)].into_iter(),
                ))
            }
            Primitive::Duration => {
                let sec = i32::from_le_bytes(r.array()?);
                let nanosec = i32::from_le_bytes(r.array()?);
                visitor.visit_map(MapDeserializer::new(
                    [("sec", sec), ("nanosec", nanosec)].into_iter(),
                ))
            }
        }
    }
}

impl<'de> de::Deserializer<'de> for Value<'_, '_, 'de> {
    type Error = Ros1Error;

    fn deserialize_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Ros1Error> {
        match self.ty {
            FieldType::Primitive(_) if self.group > 1 => {
                let (ty, group) = (self.ty, self.group);
                visitor.visit_seq(Elements {
                    reader: self.reader,
                    element: ty,
                    left: group,
                    group: 1,
                })
            }
            FieldType::Primitive(p) => self.primitive(*p, visitor),
            FieldType::Message(i) => {
                let ty = &self.reader.definition.types[*i];
                visitor.visit_map(Fields {
                    reader: self.reader,
                    ty,
                    next: 0,
                })
            }
            FieldType::Array { element, len } => {
                let count = match len {
                    Some(n) => *n,
                    None => self.reader.count(element)?,
                };
                visitor.visit_seq(Elements {
                    reader: self.reader,
                    element,
                    left: count,
                    group: 1,
                })
            }
        }
    }

    fn deserialize_bytes<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Ros1Error> {
        match self.ty {
            FieldType::Array { element, len }
                if matches!(
                    **element,
                    FieldType::Primitive(Primitive::UInt8 | Primitive::Int8)
                ) =>
            {
                let count = match len {
                    Some(n) => *n,
                    None => self.reader.count(element)?,
                };
                visitor.visit_borrowed_bytes(self.reader.take(count)?)
            }
            _ => self.deserialize_any(visitor),
        }
    }

    fn deserialize_byte_buf<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Ros1Error> {
        self.deserialize_bytes(visitor)
    }

    fn deserialize_tuple<V: Visitor<'de>>(
        self,
        len: usize,
        visitor: V,
    ) -> Result<V::Value, Ros1Error> {
        let (n, element) = match self.ty {
            FieldType::Array {
                element,
                len: Some(n),
            } => (*n, &**element),
            FieldType::Primitive(_) if self.group > 1 => (self.group, self.ty),
            _ => return self.deserialize_any(visitor),
        };
        let groups = matches!(element, FieldType::Primitive(_)) && len > 0 && n % len == 0;
        if len != n && !groups {
            return Err(Ros1Error::Custom(format!(
                "field {} holds {n} values, not {len}",
                self.reader.field
            )));
        }
        visitor.visit_seq(Elements {
            reader: self.reader,
            element,
            left: len,
            group: n / len.max(1),
        })
    }

    fn deserialize_ignored_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Ros1Error> {
        self.reader.skip(self.ty, self.group)?;
        visitor.visit_unit()
    }

    fn deserialize_option<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Ros1Error> {
        visitor.visit_some(self)
    }

    fn deserialize_newtype_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        visitor: V,
    ) -> Result<V::Value, Ros1Error> {
        visitor.visit_newtype_struct(self)
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string
        unit unit_struct seq tuple_struct map struct enum identifier
    }
}

/// A message's fields, in wire order, as a map keyed by field name.
struct Fields<'r, 'a, 'de> {
    reader: &'r mut Reader<'a, 'de>,
    ty: &'a MessageType,
    next: usize,
}

impl<'de> MapAccess<'de> for Fields<'_, '_, 'de> {
    type Error = Ros1Error;

    fn next_key_seed<K: DeserializeSeed<'de>>(
        &mut self,
        seed: K,
    ) -> Result<Option<K::Value>, Ros1Error> {
        let Some(field) = self.ty.fields.get(self.next) else {
            return Ok(None);
        };
        self.reader.field = &field.name;
        let key: StrDeserializer<'_, Ros1Error> = field.name.as_str().into_deserializer();
        seed.deserialize(key).map(Some)
    }

    fn next_value_seed<V: DeserializeSeed<'de>>(&mut self, seed: V) -> Result<V::Value, Ros1Error> {
        let field = &self.ty.fields[self.next];
        self.next += 1;
        seed.deserialize(Value {
            reader: self.reader,
            ty: &field.ty,
            group: 1,
        })
    }

    fn size_hint(&self) -> Option<usize> {
        Some(self.ty.fields.len() - self.next)
    }
}

/// The elements of an array (or of a group), each `group` primitives wide.
struct Elements<'r, 'a, 'de> {
    reader: &'r mut Reader<'a, 'de>,
    element: &'a FieldType,
    left: usize,
    group: usize,
}

impl<'de> SeqAccess<'de> for Elements<'_, '_, 'de> {
    type Error = Ros1Error;

    fn next_element_seed<T: DeserializeSeed<'de>>(
        &mut self,
        seed: T,
    ) -> Result<Option<T::Value>, Ros1Error> {
        if self.left == 0 {
            return Ok(None);
        }
        self.left -= 1;
        seed.deserialize(Value {
            reader: self.reader,
            ty: self.element,
            group: self.group,
        })
        .map(Some)
    }

    fn size_hint(&self) -> Option<usize> {
        Some(self.left)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ros::msg;

    const SEP: &str =
        "\n================================================================================\nMSG: ";

    fn definition(root: &str, parts: &[&str]) -> Definition {
        Definition::parse(root, &parts.join(SEP)).unwrap()
    }

    /// ROS 1 bytes, written field by field as `genpy` lays them out.
    #[derive(Default)]
    struct Wire(Vec<u8>);

    impl Wire {
        fn u32(mut self, v: u32) -> Self {
            self.0.extend(v.to_le_bytes());
            self
        }
        fn f64(mut self, v: f64) -> Self {
            self.0.extend(v.to_le_bytes());
            self
        }
        fn string(self, s: &str) -> Self {
            let mut w = self.u32(s.len() as u32);
            w.0.extend(s.as_bytes());
            w
        }
        fn header(self, seq: u32, secs: u32, nsecs: u32, frame: &str) -> Self {
            self.u32(seq).u32(secs).u32(nsecs).string(frame)
        }
    }

    const HEADER: &str = "std_msgs/Header\nuint32 seq\ntime stamp\nstring frame_id\n";
    const POSE: &str = "geometry_msgs/Pose\nPoint position\nQuaternion orientation\n";
    const POINT: &str = "geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n";
    const QUATERNION: &str =
        "geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n";

    #[test]
    fn odometry_with_an_extra_field_decodes_by_name() {
        // A driver's Odometry with a field ROS does not have, between two
        // that postflight reads.
        let d = definition(
            "nav_msgs/Odometry",
            &[
                "Header header\nstring child_frame_id\nuint8[] vendor_blob\ngeometry_msgs/PoseWithCovariance pose\ngeometry_msgs/TwistWithCovariance twist\n",
                HEADER,
                "geometry_msgs/PoseWithCovariance\nPose pose\nfloat64[36] covariance\n",
                POSE,
                POINT,
                QUATERNION,
                "geometry_msgs/TwistWithCovariance\nTwist twist\nfloat64[36] covariance\n",
                "geometry_msgs/Twist\nVector3 linear\nVector3 angular\n",
                "geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n",
            ],
        );
        let mut w = Wire::default()
            .header(7, 1_700_000_000, 5, "map")
            .string("base_link")
            .u32(3);
        w.0.extend([1, 2, 3]);
        for v in [1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0] {
            w = w.f64(v);
        }
        for i in 0..36 {
            w = w.f64(f64::from(i));
        }
        for v in 0..(6 + 36) {
            w = w.f64(f64::from(v) * 0.5);
        }
        let o: msg::Odometry = decode(&d, &w.0).unwrap();
        assert_eq!(o.header.frame_id, "map");
        assert_eq!(o.header.stamp.nanos(), 1_700_000_000_000_000_005);
        assert_eq!(o.child_frame_id, "base_link");
        assert_eq!(o.pose.pose.position.z, 3.0);
        assert_eq!(o.pose.pose.orientation.w, 1.0);
        assert_eq!(o.pose.covariance[2][3], 15.0);
        assert_eq!(o.twist.twist.angular.z, 2.5);
        assert_eq!(o.twist.covariance[5][5], 0.5 * 41.0);
    }

    #[test]
    fn camera_info_reads_ros1_capital_matrices_and_skips_image_data() {
        let d = definition(
            "sensor_msgs/CameraInfo",
            &[
                "Header header\nuint32 height\nuint32 width\nstring distortion_model\nfloat64[] D\nfloat64[9] K\nfloat64[9] R\nfloat64[12] P\nuint32 binning_x\nuint32 binning_y\nRegionOfInterest roi\n",
                HEADER,
                "sensor_msgs/RegionOfInterest\nuint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify\n",
            ],
        );
        let mut w = Wire::default()
            .header(1, 10, 0, "cam")
            .u32(48)
            .u32(64)
            .string("plumb_bob")
            .u32(5);
        for v in 0..(5 + 9 + 9 + 12) {
            w = w.f64(f64::from(v));
        }
        w = w.u32(0).u32(0).u32(1).u32(2).u32(3).u32(4);
        w.0.push(1);
        let info: msg::CameraInfo = decode(&d, &w.0).unwrap();
        assert_eq!(info.d, [0.0, 1.0, 2.0, 3.0, 4.0]);
        assert_eq!(info.k[0], 5.0);
        assert_eq!(info.p[11], 34.0);
        assert!(info.roi.do_rectify);

        let image = definition(
            "sensor_msgs/Image",
            &[
                "Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\nuint32 step\nuint8[] data\n",
                HEADER,
            ],
        );
        let mut w = Wire::default()
            .header(1, 10, 0, "cam")
            .u32(1)
            .u32(2)
            .string("mono8");
        w.0.push(0);
        w = w.u32(2).u32(2);
        w.0.extend([9, 8]);
        let head: msg::ImageHead = decode(&image, &w.0).unwrap();
        assert_eq!(
            (head.width, head.step, head.encoding.as_str()),
            (2, 2, "mono8")
        );
        let whole: msg::Image = decode(&image, &w.0).unwrap();
        assert_eq!(whole.data, [9, 8]);
    }

    #[test]
    fn cut_messages_and_absurd_lengths_are_errors_not_allocations() {
        let d = definition("a/B", &["string name\nfloat64[] values\n"]);
        let w = Wire::default().string("x").u32(u32::MAX);
        #[derive(Debug, Deserialize)]
        #[allow(dead_code)]
        struct B {
            name: String,
            values: Vec<f64>,
        }
        let err = decode::<B>(&d, &w.0).unwrap_err();
        assert!(matches!(err, Ros1Error::Length { .. }), "{err}");
        let full = Wire::default().string("x").u32(1).f64(2.0);
        for cut in 0..full.0.len() {
            let err = decode::<B>(&d, &full.0[..cut]).unwrap_err();
            assert!(
                matches!(err, Ros1Error::Truncated { .. } | Ros1Error::Length { .. }),
                "cut {cut}: {err}"
            );
        }
        assert_eq!(decode::<B>(&d, &full.0).unwrap().values, [2.0]);
    }
}
