//! Decoding of ROS 2 CDR payloads (the 4-byte encapsulation header, then
//! XCDR1 plain data) into the structs of [`super::msg`].

use serde::Serialize;
use serde::de::DeserializeOwned;

/// Why a CDR payload could not be decoded.
#[derive(Debug, thiserror::Error)]
pub enum CdrError {
    #[error("payload shorter than the 4-byte CDR encapsulation header")]
    TooShort,
    #[error("unsupported CDR encapsulation kind {0:#04x} (only plain CDR, big or little endian)")]
    Encapsulation(u8),
    #[error("{0}")]
    Decode(#[from] cdr::Error),
    #[error("byte sequence runs past the end of the message")]
    Truncated,
}

/// Byte order of a CDR payload, from its encapsulation header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Endian {
    Big,
    Little,
}

fn encapsulation(payload: &[u8]) -> Result<(Endian, &[u8]), CdrError> {
    if payload.len() < 4 {
        return Err(CdrError::TooShort);
    }
    // Kinds 0/1 are CDR_BE/CDR_LE; 2/3 are the parameter-list variants, which
    // ROS 2 does not use for plain messages.
    let endian = match payload[1] {
        0x00 => Endian::Big,
        0x01 => Endian::Little,
        other => return Err(CdrError::Encapsulation(other)),
    };
    Ok((endian, &payload[4..]))
}

/// Encode a message as ROS 2 does: little-endian plain CDR.
pub fn encode<T: Serialize>(msg: &T) -> Vec<u8> {
    cdr::serialize::<_, _, cdr::CdrLe>(msg, cdr::Infinite)
        .expect("in-memory CDR encoding cannot fail")
}

/// Decode a whole message.
pub fn decode<T: DeserializeOwned>(payload: &[u8]) -> Result<T, CdrError> {
    Ok(decode_head::<T>(payload)?.0)
}

/// Decode the leading fields of a message described by `T`, returning the
/// value and a [`Tail`] positioned at the next field.
pub fn decode_head<T: DeserializeOwned>(payload: &[u8]) -> Result<(T, Tail<'_>), CdrError> {
    let (endian, body) = encapsulation(payload)?;
    let mut rest: &[u8] = body;
    let value = match endian {
        Endian::Big => {
            cdr::de::deserialize_data_from::<_, T, _, cdr::BigEndian>(&mut rest, cdr::Infinite)?
        }
        Endian::Little => {
            cdr::de::deserialize_data_from::<_, T, _, cdr::LittleEndian>(&mut rest, cdr::Infinite)?
        }
    };
    let pos = body.len() - rest.len();
    Ok((value, Tail { body, pos, endian }))
}

/// The undecoded remainder of a CDR message body.
#[derive(Debug, Clone, Copy)]
pub struct Tail<'a> {
    body: &'a [u8],
    pos: usize,
    endian: Endian,
}

impl<'a> Tail<'a> {
    /// Borrow the next `sequence<uint8>` field without copying it.
    pub fn byte_sequence(&mut self) -> Result<&'a [u8], CdrError> {
        // The u32 length is aligned to 4 relative to the body start.
        let start = self.pos.next_multiple_of(4);
        let len_bytes: [u8; 4] = self
            .body
            .get(start..start + 4)
            .and_then(|b| b.try_into().ok())
            .ok_or(CdrError::Truncated)?;
        let len = match self.endian {
            Endian::Big => u32::from_be_bytes(len_bytes),
            Endian::Little => u32::from_le_bytes(len_bytes),
        } as usize;
        let data = self
            .body
            .get(start + 4..start + 4 + len)
            .ok_or(CdrError::Truncated)?;
        self.pos = start + 4 + len;
        Ok(data)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ros::msg::{CompressedImageHead, Header};

    fn le_string(out: &mut Vec<u8>, s: &str) {
        while !(out.len() - 4).is_multiple_of(4) {
            out.push(0);
        }
        out.extend_from_slice(&(s.len() as u32 + 1).to_le_bytes());
        out.extend_from_slice(s.as_bytes());
        out.push(0);
    }

    #[test]
    fn head_then_borrowed_bytes() {
        let mut p = vec![0, 1, 0, 0];
        p.extend_from_slice(&7i32.to_le_bytes());
        p.extend_from_slice(&9u32.to_le_bytes());
        le_string(&mut p, "cam");
        le_string(&mut p, "jpeg");
        while !(p.len() - 4).is_multiple_of(4) {
            p.push(0);
        }
        p.extend_from_slice(&3u32.to_le_bytes());
        p.extend_from_slice(&[0xff, 0xd8, 0xff]);
        let (head, mut tail) = decode_head::<CompressedImageHead>(&p).unwrap();
        assert_eq!(head.header.stamp.nanos(), 7_000_000_009);
        assert_eq!(head.header.frame_id, "cam");
        assert_eq!(head.format, "jpeg");
        assert_eq!(tail.byte_sequence().unwrap(), &[0xff, 0xd8, 0xff]);
        assert!(tail.byte_sequence().is_err());
    }

    #[test]
    fn encode_decode_round_trip() {
        use crate::ros::msg::{CompressedImage, Time};
        let msg = CompressedImage {
            header: Header {
                stamp: Time { sec: 3, nanosec: 4 },
                frame_id: "camera_optical".into(),
            },
            format: "jpeg".into(),
            data: vec![1, 2, 3, 4, 5],
        };
        let bytes = encode(&msg);
        assert_eq!(&bytes[..4], &[0, 1, 0, 0]);
        let back: CompressedImage = decode(&bytes).unwrap();
        assert_eq!(back.data, msg.data);
        assert_eq!(back.header.frame_id, "camera_optical");
    }

    #[test]
    fn rejects_short_and_unknown_encapsulation() {
        assert!(matches!(decode::<Header>(&[0, 1]), Err(CdrError::TooShort)));
        assert!(matches!(
            decode::<Header>(&[0, 9, 0, 0, 0, 0]),
            Err(CdrError::Encapsulation(9))
        ));
    }
}
