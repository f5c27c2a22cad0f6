//! How a channel's messages are serialised, and decoding them into the
//! structs of [`super::msg`] whichever it is: ROS 2 CDR, or ROS 1 by the
//! definition the recording carries (bags, and MCAP with the `ros1` profile).

use std::sync::Arc;

use serde::Deserialize;
use serde::de::DeserializeOwned;

use super::cdr;
use super::msg::{CompressedImageHead, Header, ImageHead};
use super::ros1::{self, Definition, DefinitionError};

/// A message's serialisation.
#[derive(Debug, Clone)]
pub enum Wire {
    /// ROS 2: CDR, laid out as the `.msg` field order (message encoding `cdr`).
    Cdr,
    /// ROS 1, decoded by the channel's definition (message encoding `ros1`).
    Ros1(Arc<Definition>),
}

/// Why a channel's messages cannot be decoded, or one message could not be.
#[derive(Debug, Clone, thiserror::Error)]
pub enum DecodeError {
    #[error("{0}")]
    Cdr(String),
    #[error(transparent)]
    Ros1(#[from] ros1::Ros1Error),
    #[error("its message definition cannot be parsed: {0}")]
    Definition(#[from] DefinitionError),
    #[error("message encoding {0:?} is neither cdr (ROS 2) nor ros1")]
    Encoding(String),
}

impl From<cdr::CdrError> for DecodeError {
    fn from(e: cdr::CdrError) -> Self {
        Self::Cdr(e.to_string())
    }
}

/// The message encodings postflight reads, as MCAP channels name them.
pub mod encoding {
    pub const CDR: &str = "cdr";
    pub const ROS1: &str = "ros1";
}

impl Wire {
    /// The wire of a channel: its message encoding, and for ROS 1 its type
    /// (`sensor_msgs/Image`) and definition text.
    pub fn of(message_encoding: &str, schema: &str, definition: &str) -> Result<Self, DecodeError> {
        match message_encoding {
            encoding::CDR => Ok(Self::Cdr),
            encoding::ROS1 => Ok(Self::Ros1(Arc::new(Definition::parse(schema, definition)?))),
            other => Err(DecodeError::Encoding(other.to_string())),
        }
    }

    /// The message encoding's name.
    pub fn encoding(&self) -> &'static str {
        match self {
            Self::Cdr => encoding::CDR,
            Self::Ros1(_) => encoding::ROS1,
        }
    }

    /// Decode a whole message.
    pub fn decode<T: DeserializeOwned>(&self, data: &[u8]) -> Result<T, DecodeError> {
        Ok(match self {
            Self::Cdr => cdr::decode(data)?,
            Self::Ros1(definition) => ros1::decode(definition, data)?,
        })
    }

    /// An Image's head and its pixel bytes, borrowed.
    pub fn image<'a>(&self, data: &'a [u8]) -> Result<(ImageHead, &'a [u8]), DecodeError> {
        match self {
            Self::Cdr => {
                let (head, mut tail) = cdr::decode_head::<ImageHead>(data)?;
                Ok((head, tail.byte_sequence()?))
            }
            Self::Ros1(definition) => {
                let image: ImageView<'a> = ros1::decode(definition, data)?;
                let head = ImageHead {
                    header: image.header,
                    height: image.height,
                    width: image.width,
                    encoding: image.encoding,
                    is_bigendian: image.is_bigendian,
                    step: image.step,
                };
                Ok((head, image.data))
            }
        }
    }

    /// A CompressedImage's head and its JPEG or PNG bytes, borrowed.
    pub fn compressed_image<'a>(
        &self,
        data: &'a [u8],
    ) -> Result<(CompressedImageHead, &'a [u8]), DecodeError> {
        match self {
            Self::Cdr => {
                let (head, mut tail) = cdr::decode_head::<CompressedImageHead>(data)?;
                Ok((head, tail.byte_sequence()?))
            }
            Self::Ros1(definition) => {
                let image: CompressedImageView<'a> = ros1::decode(definition, data)?;
                let head = CompressedImageHead {
                    header: image.header,
                    format: image.format,
                };
                Ok((head, image.data))
            }
        }
    }
}

/// `sensor_msgs/Image` with its pixels borrowed (ROS 1 fields by name).
#[derive(Deserialize)]
struct ImageView<'a> {
    header: Header,
    height: u32,
    width: u32,
    encoding: String,
    is_bigendian: u8,
    step: u32,
    #[serde(borrow, with = "serde_bytes")]
    data: &'a [u8],
}

/// `sensor_msgs/CompressedImage` with its bytes borrowed.
#[derive(Deserialize)]
struct CompressedImageView<'a> {
    header: Header,
    format: String,
    #[serde(borrow, with = "serde_bytes")]
    data: &'a [u8],
}
