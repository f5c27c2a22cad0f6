//! Kinds: enums whose every variant has a name, as tables and files spell
//! it (`+x`, `no_surface`, `needs_repair`). A kind is declared once with
//! [`kind!`](crate::kind!), one line per variant with its name; its name
//! lookup ([`Named`]), `as_str`, serde by name (so a kind can key a JSON
//! object: `{"too_far": 12}`) and its counts ([`Counts`]) follow.

use std::fmt;
use std::marker::PhantomData;

/// A kind stored by its name.
pub trait Named: Sized + Copy + 'static {
    /// Every kind, in declaration order.
    const ALL: &'static [Self];
    /// Its name, as tables and files spell it.
    fn name(self) -> &'static str;
    /// The kind named `name`.
    fn named(name: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|k| k.name() == name)
    }
    /// Its place in [`Named::ALL`].
    fn index(self) -> usize {
        Self::ALL
            .iter()
            .position(|k| k.name() == self.name())
            .expect("every kind is in ALL")
    }
}

/// A kind given on the command line by its name (a flag's `value_parser`):
/// an unknown name's error lists the names there are.
pub fn parse_named<K: Named>(text: &str) -> Result<K, String> {
    K::named(text).ok_or_else(|| {
        let names: Vec<&str> = K::ALL.iter().map(|k| k.name()).collect();
        format!("'{text}' is none of {}", names.join(", "))
    })
}

/// Declare a kind: a fieldless enum, each variant with its doc and name.
/// Gives `Debug`, `Clone`, `Copy`, equality, order (by declaration),
/// `Hash`, `as_str`, [`Named`] and serde by name; `$what` words an unknown
/// name's error (`unknown outcome "x"`).
///
/// ```
/// postflight_core::kind! {
///     /// How a thing went.
///     pub enum Went("way it went") {
///         /// Well.
///         Well = "well",
///         /// Not at all.
///         NotAtAll = "not_at_all",
///     }
/// }
/// assert_eq!(Went::NotAtAll.as_str(), "not_at_all");
/// ```
#[macro_export]
macro_rules! kind {
    (
        $(#[$meta:meta])*
        $vis:vis enum $kind:ident ($what:literal) {
            $( $(#[$vmeta:meta])* $variant:ident = $name:literal, )+
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
        $vis enum $kind {
            $( $(#[$vmeta])* $variant, )+
        }

        impl $kind {
            /// Every kind, in declaration order.
            pub const ALL: &'static [Self] = &[ $( Self::$variant, )+ ];

            /// Its name, as tables and files spell it.
            pub fn as_str(self) -> &'static str {
                match self {
                    $( Self::$variant => $name, )+
                }
            }
        }

        impl $crate::kind::Named for $kind {
            const ALL: &'static [Self] = Self::ALL;
            fn name(self) -> &'static str {
                self.as_str()
            }
            fn index(self) -> usize {
                self as usize
            }
        }

        $crate::serde_by_name!($kind, $what);
    };
}

/// Serialize and deserialize a [`Named`] kind as its name, so it can key a
/// JSON object; for kinds [`kind!`](crate::kind!) cannot declare (a
/// variant that holds another kind).
#[macro_export]
macro_rules! serde_by_name {
    ($kind:ty, $what:literal) => {
        impl $crate::kind::__serde::Serialize for $kind {
            fn serialize<S: $crate::kind::__serde::Serializer>(
                &self,
                to: S,
            ) -> Result<S::Ok, S::Error> {
                to.serialize_str($crate::kind::Named::name(*self))
            }
        }

        impl<'de> $crate::kind::__serde::Deserialize<'de> for $kind {
            fn deserialize<D: $crate::kind::__serde::Deserializer<'de>>(
                from: D,
            ) -> Result<Self, D::Error> {
                let name = <String as $crate::kind::__serde::Deserialize>::deserialize(from)?;
                <Self as $crate::kind::Named>::named(&name).ok_or_else(|| {
                    <D::Error as $crate::kind::__serde::de::Error>::custom(format!(
                        concat!("unknown ", $what, " {:?}"),
                        name
                    ))
                })
            }
        }
    };
}

#[doc(hidden)]
pub use serde as __serde;

/// How many of each kind: in JSON an object with every kind's name, in
/// declaration order, zeros included (`{"placed": 12, "no_pose": 0}`).
#[derive(Clone, PartialEq, Eq)]
pub struct Counts<K: Named> {
    counts: Vec<u64>,
    kind: PhantomData<K>,
}

impl<K: Named> Counts<K> {
    /// How many of `kind`.
    pub fn get(&self, kind: K) -> u64 {
        self.counts[kind.index()]
    }

    /// One more of `kind`.
    pub fn add(&mut self, kind: K) {
        self.add_many(kind, 1);
    }

    /// `n` more of `kind`.
    pub fn add_many(&mut self, kind: K, n: u64) {
        self.counts[kind.index()] += n;
    }

    /// `other`'s counts added to these.
    pub fn add_all(&mut self, other: &Self) {
        for (kind, n) in other.iter() {
            self.add_many(kind, n);
        }
    }

    /// Every kind with its count, in declaration order.
    pub fn iter(&self) -> impl Iterator<Item = (K, u64)> + '_ {
        K::ALL.iter().copied().zip(self.counts.iter().copied())
    }

    /// All of them.
    pub fn total(&self) -> u64 {
        self.counts.iter().sum()
    }
}

impl<K: Named> Default for Counts<K> {
    fn default() -> Self {
        Self {
            counts: vec![0; K::ALL.len()],
            kind: PhantomData,
        }
    }
}

impl<K: Named> FromIterator<K> for Counts<K> {
    fn from_iter<I: IntoIterator<Item = K>>(kinds: I) -> Self {
        let mut counts = Self::default();
        for kind in kinds {
            counts.add(kind);
        }
        counts
    }
}

impl<K: Named> fmt::Debug for Counts<K> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_map()
            .entries(self.iter().map(|(k, n)| (k.name(), n)))
            .finish()
    }
}

impl<K: Named> serde::Serialize for Counts<K> {
    fn serialize<S: serde::Serializer>(&self, to: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut map = to.serialize_map(Some(K::ALL.len()))?;
        for (kind, n) in self.iter() {
            map.serialize_entry(kind.name(), &n)?;
        }
        map.end()
    }
}

impl<'de, K: Named> serde::Deserialize<'de> for Counts<K> {
    /// Every name must be a kind's; a kind left out counts 0.
    fn deserialize<D: serde::Deserializer<'de>>(from: D) -> Result<Self, D::Error> {
        let named = std::collections::BTreeMap::<String, u64>::deserialize(from)?;
        let mut counts = Self::default();
        for (name, n) in named {
            let kind = K::named(&name).ok_or_else(|| {
                let names: Vec<&str> = K::ALL.iter().map(|k| k.name()).collect();
                serde::de::Error::custom(format!(
                    "unknown {name:?}, expected one of {}",
                    names.join(", ")
                ))
            })?;
            counts.counts[kind.index()] = n;
        }
        Ok(counts)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    crate::kind! {
        /// A test kind.
        enum Fruit("fruit") {
            /// Red.
            Apple = "apple",
            /// Long.
            BlueBanana = "blue_banana",
        }
    }

    #[test]
    fn a_kind_reads_and_writes_by_its_name_and_counts_in_order() {
        assert_eq!(Fruit::named("blue_banana"), Some(Fruit::BlueBanana));
        assert_eq!(serde_json::to_string(&Fruit::Apple).unwrap(), "\"apple\"");
        let err = serde_json::from_str::<Fruit>("\"pear\"").unwrap_err();
        assert!(err.to_string().contains("unknown fruit \"pear\""), "{err}");
        let counts: Counts<Fruit> = [Fruit::BlueBanana, Fruit::BlueBanana].into_iter().collect();
        let json = serde_json::to_string(&counts).unwrap();
        assert_eq!(json, r#"{"apple":0,"blue_banana":2}"#);
        let back: Counts<Fruit> = serde_json::from_str(r#"{"blue_banana":2}"#).unwrap();
        assert_eq!(back, counts);
        assert!(serde_json::from_str::<Counts<Fruit>>(r#"{"pear":1}"#).is_err());
        assert_eq!(counts.total(), 2);
    }
}
