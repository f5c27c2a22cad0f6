//! ROS 1 serialisation: message definitions as recordings carry them
//! ([`definition`]) and decoding messages by them ([`decode`]), so any
//! field layout a ROS 1 stack recorded reads into postflight's message
//! structs ([`super::msg`]).

pub mod decode;
pub mod definition;

pub use decode::{Ros1Error, decode};
pub use definition::{Definition, DefinitionError};
