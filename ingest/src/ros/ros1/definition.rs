//! ROS 1 message definitions as recordings carry them: the `.msg` text of
//! the message type, then each type it uses after a `====` line and a
//! `MSG: package/Type` line (a bag connection's `message_definition`, an
//! MCAP `ros1msg` schema). Parsed once per connection into a [`Definition`]
//! that [`super::decode`] walks.

use std::collections::HashMap;

/// Why a message definition could not be parsed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DefinitionError {
    #[error("line {line} of the definition of {ty}: {why}")]
    Line {
        ty: String,
        line: usize,
        why: String,
    },
    #[error("{ty} uses {used}, which the definition does not carry")]
    Missing { ty: String, used: String },
    #[error("{ty} contains itself (through {through})")]
    Recursive { ty: String, through: String },
}

/// A primitive ROS 1 field type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Primitive {
    Bool,
    Int8,
    UInt8,
    Int16,
    UInt16,
    Int32,
    UInt32,
    Int64,
    UInt64,
    Float32,
    Float64,
    String,
    /// `time`: seconds and nanoseconds, both `uint32`.
    Time,
    /// `duration`: seconds and nanoseconds, both `int32`.
    Duration,
}

impl Primitive {
    fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "bool" => Self::Bool,
            // `byte` and `char` are deprecated aliases of int8 and uint8.
            "int8" | "byte" => Self::Int8,
            "uint8" | "char" => Self::UInt8,
            "int16" => Self::Int16,
            "uint16" => Self::UInt16,
            "int32" => Self::Int32,
            "uint32" => Self::UInt32,
            "int64" => Self::Int64,
            "uint64" => Self::UInt64,
            "float32" => Self::Float32,
            "float64" => Self::Float64,
            "string" => Self::String,
            "time" => Self::Time,
            "duration" => Self::Duration,
            _ => return None,
        })
    }

    /// Bytes on the wire; a string's is its least (the length prefix).
    pub fn size(self) -> usize {
        match self {
            Self::Bool | Self::Int8 | Self::UInt8 => 1,
            Self::Int16 | Self::UInt16 => 2,
            Self::Int32 | Self::UInt32 | Self::Float32 | Self::String => 4,
            Self::Int64 | Self::UInt64 | Self::Float64 | Self::Time | Self::Duration => 8,
        }
    }
}

/// A field's type.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum FieldType {
    Primitive(Primitive),
    /// A message type, by its index in [`Definition::types`].
    Message(usize),
    /// `T[]` (`len: None`, length-prefixed) or `T[N]`.
    Array {
        element: Box<FieldType>,
        len: Option<usize>,
    },
}

/// A named field of a message type.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Field {
    pub name: String,
    pub ty: FieldType,
}

/// One message type: its full name and fields in wire order (constants
/// dropped: they are not on the wire).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MessageType {
    pub name: String,
    pub fields: Vec<Field>,
    /// Least bytes a message of this type takes on the wire.
    pub min_size: usize,
}

/// A parsed definition: the root type is `types[0]`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Definition {
    pub types: Vec<MessageType>,
}

impl Definition {
    /// Parse the definition of `root` (e.g. `sensor_msgs/Image`).
    pub fn parse(root: &str, text: &str) -> Result<Self, DefinitionError> {
        let sections = sections(root, text)?;
        let index: HashMap<&str, usize> = sections
            .iter()
            .enumerate()
            .map(|(i, s)| (s.name.as_str(), i))
            .collect();
        let mut types = Vec::with_capacity(sections.len());
        for section in &sections {
            let fields = section
                .fields
                .iter()
                .map(|(name, ty, line)| {
                    Ok(Field {
                        name: name.clone(),
                        ty: resolve(ty, &section.name, *line, &index)?,
                    })
                })
                .collect::<Result<Vec<_>, _>>()?;
            types.push(MessageType {
                name: section.name.clone(),
                fields,
                min_size: 0,
            });
        }
        let mut definition = Self { types };
        definition.check_acyclic()?;
        definition.compute_min_sizes();
        Ok(definition)
    }

    /// The root message type.
    pub fn root(&self) -> &MessageType {
        &self.types[0]
    }

    /// Least bytes a value of `ty` takes on the wire.
    pub fn min_size(&self, ty: &FieldType) -> usize {
        match ty {
            FieldType::Primitive(p) => p.size(),
            FieldType::Message(i) => self.types[*i].min_size,
            FieldType::Array { len: None, .. } => 4,
            FieldType::Array {
                element,
                len: Some(n),
            } => self.min_size(element).saturating_mul(*n),
        }
    }

    /// ROS messages cannot contain themselves; a definition that says so
    /// is damaged, and decoding it would not end.
    fn check_acyclic(&self) -> Result<(), DefinitionError> {
        fn visit(
            d: &Definition,
            i: usize,
            path: &mut Vec<usize>,
            done: &mut [bool],
        ) -> Result<(), DefinitionError> {
            if done[i] {
                return Ok(());
            }
            if path.contains(&i) {
                return Err(DefinitionError::Recursive {
                    ty: d.types[i].name.clone(),
                    through: path
                        .iter()
                        .map(|&p| d.types[p].name.as_str())
                        .collect::<Vec<_>>()
                        .join(" -> "),
                });
            }
            path.push(i);
            for field in &d.types[i].fields {
                if let Some(j) = message_of(&field.ty) {
                    visit(d, j, path, done)?;
                }
            }
            path.pop();
            done[i] = true;
            Ok(())
        }
        let mut done = vec![false; self.types.len()];
        visit(self, 0, &mut Vec::new(), &mut done)
    }

    fn compute_min_sizes(&mut self) {
        // Acyclic, so depth-first order settles every type before its users.
        fn size(d: &mut Definition, i: usize, known: &mut [Option<usize>]) -> usize {
            if let Some(s) = known[i] {
                return s;
            }
            let fields: Vec<FieldType> = d.types[i].fields.iter().map(|f| f.ty.clone()).collect();
            let mut total = 0usize;
            for ty in &fields {
                if let Some(j) = message_of(ty) {
                    size(d, j, known);
                }
                total = total.saturating_add(field_size(ty, known));
            }
            known[i] = Some(total);
            d.types[i].min_size = total;
            total
        }
        fn field_size(ty: &FieldType, known: &[Option<usize>]) -> usize {
            match ty {
                FieldType::Primitive(p) => p.size(),
                FieldType::Message(j) => known[*j].unwrap_or(0),
                FieldType::Array { len: None, .. } => 4,
                FieldType::Array {
                    element,
                    len: Some(n),
                } => field_size(element, known).saturating_mul(*n),
            }
        }
        let mut known = vec![None; self.types.len()];
        for i in 0..self.types.len() {
            size(self, i, &mut known);
        }
    }
}

/// The message type a field uses, directly or as array elements.
fn message_of(ty: &FieldType) -> Option<usize> {
    match ty {
        FieldType::Message(i) => Some(*i),
        FieldType::Array { element, .. } => message_of(element),
        FieldType::Primitive(_) => None,
    }
}

/// A type's section of the text: its name and `(field, type text)` pairs.
struct Section {
    name: String,
    /// `(field, type text, line)`.
    fields: Vec<(String, String, usize)>,
}

fn sections(root: &str, text: &str) -> Result<Vec<Section>, DefinitionError> {
    let mut sections = vec![Section {
        name: normalise(root),
        fields: Vec::new(),
    }];
    let mut expect_name = false;
    for (n, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if line.len() >= 3 && line.bytes().all(|b| b == b'=') {
            expect_name = true;
            continue;
        }
        let current = sections.last().map(|s| s.name.clone()).unwrap_or_default();
        let bad = |why: String| DefinitionError::Line {
            ty: current.clone(),
            line: n + 1,
            why,
        };
        if expect_name {
            if line.is_empty() {
                continue;
            }
            let name = line
                .strip_prefix("MSG:")
                .ok_or_else(|| bad(format!("expected `MSG: package/Type`, found {line:?}")))?;
            sections.push(Section {
                name: normalise(name.trim()),
                fields: Vec::new(),
            });
            expect_name = false;
            continue;
        }
        let code = line.split('#').next().unwrap_or("").trim();
        if code.is_empty() {
            continue;
        }
        let mut words = code.splitn(2, char::is_whitespace);
        let ty = words.next().unwrap_or("");
        let rest = words.next().unwrap_or("").trim();
        if rest.is_empty() {
            return Err(bad(format!("{code:?} has a type but no field name")));
        }
        // `TYPE NAME=VALUE` declares a constant, which is not on the wire.
        if rest.contains('=') {
            continue;
        }
        if !rest.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_') {
            return Err(bad(format!("{rest:?} is not a field name")));
        }
        let section = sections
            .last_mut()
            .expect("the root section is always there");
        section
            .fields
            .push((rest.to_string(), ty.to_string(), n + 1));
    }
    Ok(sections)
}

/// `pkg/msg/Type` (as ROS 2 tools write ROS 1 names) to `pkg/Type`.
fn normalise(name: &str) -> String {
    name.replace("/msg/", "/")
}

fn resolve(
    text: &str,
    owner: &str,
    line: usize,
    index: &HashMap<&str, usize>,
) -> Result<FieldType, DefinitionError> {
    if let Some(open) = text.find('[') {
        let inner = &text[open + 1..];
        let close = inner.find(']').filter(|&c| c + 1 == inner.len());
        let Some(close) = close else {
            return Err(DefinitionError::Line {
                ty: owner.to_string(),
                line,
                why: format!("{text:?} is not an array type"),
            });
        };
        let len = match inner[..close].trim() {
            "" => None,
            n => Some(n.parse::<usize>().map_err(|_| DefinitionError::Line {
                ty: owner.to_string(),
                line,
                why: format!("array length {n:?} is not a number"),
            })?),
        };
        return Ok(FieldType::Array {
            element: Box::new(resolve(&text[..open], owner, line, index)?),
            len,
        });
    }
    if let Some(p) = Primitive::parse(text) {
        return Ok(FieldType::Primitive(p));
    }
    let text = normalise(text);
    let package = owner.split('/').next().unwrap_or("");
    let candidates = if text.contains('/') {
        vec![text.clone()]
    } else if text == "Header" {
        vec!["std_msgs/Header".to_string()]
    } else {
        vec![format!("{package}/{text}")]
    };
    candidates
        .iter()
        .find_map(|c| index.get(c.as_str()).copied())
        // Writers differ in how they name dependencies; a unique type of
        // that base name is the one meant.
        .or_else(|| {
            let base = text.rsplit('/').next().unwrap_or(&text);
            let mut matching = index
                .iter()
                .filter(|(name, _)| name.rsplit('/').next() == Some(base));
            match (matching.next(), matching.next()) {
                (Some((_, &i)), None) => Some(i),
                _ => None,
            }
        })
        .map(FieldType::Message)
        .ok_or_else(|| DefinitionError::Missing {
            ty: owner.to_string(),
            used: text,
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    const POSE_STAMPED: &str = "# A pose with a header\nHeader header\ngeometry_msgs/Pose pose\n\
================================================================================\n\
MSG: std_msgs/Header\nuint32 seq\ntime stamp\nstring frame_id\n\
================================================================================\n\
MSG: geometry_msgs/Pose\nPoint position\nQuaternion orientation\n\
================================================================================\n\
MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n\
================================================================================\n\
MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n";

    #[test]
    fn a_bag_definition_resolves_header_and_package_relative_names() {
        let d = Definition::parse("geometry_msgs/PoseStamped", POSE_STAMPED).unwrap();
        let root = d.root();
        assert_eq!(root.name, "geometry_msgs/PoseStamped");
        let names: Vec<_> = root.fields.iter().map(|f| f.name.as_str()).collect();
        assert_eq!(names, ["header", "pose"]);
        let FieldType::Message(pose) = root.fields[1].ty else {
            panic!("pose is a message")
        };
        assert_eq!(d.types[pose].name, "geometry_msgs/Pose");
        // seq + time + string length, then 7 float64.
        assert_eq!(root.min_size, 4 + 8 + 4 + 7 * 8);
    }

    #[test]
    fn constants_and_comments_are_not_fields() {
        let d = Definition::parse(
            "sensor_msgs/PointField",
            "uint8 INT8=1 # a constant\nstring S=a#b\nstring name # the name\nuint32 offset\n",
        )
        .unwrap();
        let names: Vec<_> = d.root().fields.iter().map(|f| f.name.as_str()).collect();
        assert_eq!(names, ["name", "offset"]);
    }

    #[test]
    fn arrays_fixed_and_variable() {
        let d = Definition::parse("a/B", "float64[36] covariance\nuint8[] data\n").unwrap();
        assert_eq!(
            d.root().fields[0].ty,
            FieldType::Array {
                element: Box::new(FieldType::Primitive(Primitive::Float64)),
                len: Some(36)
            }
        );
        assert_eq!(d.root().min_size, 36 * 8 + 4);
    }

    #[test]
    fn a_missing_or_recursive_type_is_an_error() {
        let missing = Definition::parse("a/B", "a/C c\n").unwrap_err();
        assert!(
            matches!(missing, DefinitionError::Missing { .. }),
            "{missing}"
        );
        let recursive =
            Definition::parse("a/B", "C c\n=====\nMSG: a/C\nB[] children\n").unwrap_err();
        assert!(
            matches!(recursive, DefinitionError::Recursive { .. }),
            "{recursive}"
        );
        let junk = Definition::parse("a/B", "float64\n").unwrap_err();
        assert!(junk.to_string().contains("line 1"), "{junk}");
    }
}
