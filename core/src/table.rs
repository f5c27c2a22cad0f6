//! Tables declared once. A table is a row type made by [`table!`]: each
//! field is a column (its name, type and doc), and the writer
//! ([`Row::frame`]) and reader ([`Row::rows`]) follow from the fields.
//!
//! A field's type says how its column is stored ([`Cell`]): numbers and
//! flags as themselves, text as UTF-8, kinds (a face, an outcome) by their
//! names ([`Named`]), a list of kinds as their names joined by `,`;
//! `Option` makes a column nullable. A field whose type is itself a row
//! type adds that row's columns in its place: a group of columns several
//! tables share, such as the flight naming each row of a fleet table.
//! A field can also name its columns otherwise (see [`table!`]), so that a
//! record keeps its own shape (a position as `[x, y, z]`, an optional
//! measurement as `Option<_>`) and is still its table's row.

use polars::prelude::{BooleanChunked, DataType, IdxCa, IdxSize, polars_err};
pub use polars::prelude::{Column, DataFrame, PolarsResult};

/// Values that make columns of a table: one column (a [`Cell`]) or a
/// row's several (a [`table!`] type). A cell's column is named
/// `{prefix}{name}`; a group's columns are its fields', each after
/// `prefix`.
pub trait Columns: Sized {
    /// Append the columns of `values`, the field `name` of each row.
    fn write(prefix: &str, name: &str, values: &[&Self], out: &mut Vec<Column>);
    /// Read them back from `table`, one value per row.
    fn read(prefix: &str, name: &str, table: &DataFrame) -> PolarsResult<Vec<Self>>;
    /// Append the names of the columns it makes.
    fn names(prefix: &str, name: &str, out: &mut Vec<String>);
}

/// A row type made by [`table!`]: a whole table's columns.
pub trait Row: Columns {
    /// The table of `rows`.
    fn frame(rows: &[Self]) -> PolarsResult<DataFrame> {
        let refs: Vec<&Self> = rows.iter().collect();
        let mut columns = Vec::new();
        Self::write("", "", &refs, &mut columns);
        DataFrame::new(rows.len(), columns)
    }

    /// The rows of `table`; an error names the column (and row) that does
    /// not hold what the row type declares.
    fn rows(table: &DataFrame) -> PolarsResult<Vec<Self>> {
        Self::read("", "", table)
    }

    /// Its columns' names, in order.
    fn column_names() -> Vec<String> {
        let mut names = Vec::new();
        Self::names("", "", &mut names);
        names
    }
}

/// A value one column holds per row.
pub trait Cell: Sized {
    /// The column named `name` of these values.
    fn column(name: &str, values: &[&Self]) -> Column;
    /// A column's values; an error names the column and the row.
    fn values(column: &Column) -> PolarsResult<Vec<Self>>;
    /// What a table written before this column existed holds in it:
    /// nothing, for a nullable column; a required column must be there.
    fn absent() -> Option<Self> {
        None
    }
}

impl<T: Cell> Columns for T {
    fn write(prefix: &str, name: &str, values: &[&Self], out: &mut Vec<Column>) {
        out.push(T::column(&format!("{prefix}{name}"), values));
    }

    fn read(prefix: &str, name: &str, table: &DataFrame) -> PolarsResult<Vec<Self>> {
        match (table.column(&format!("{prefix}{name}")), T::absent()) {
            (Ok(column), _) => T::values(column),
            (Err(_), Some(_)) => Ok((0..table.height()).filter_map(|_| T::absent()).collect()),
            (Err(e), None) => Err(e),
        }
    }

    fn names(prefix: &str, name: &str, out: &mut Vec<String>) {
        out.push(format!("{prefix}{name}"));
    }
}

/// An array's columns, one per element, named `names` (a position's
/// `x`, `y`, `z`).
pub fn write_axes<T: Columns, const N: usize>(
    prefix: &str,
    names: [&str; N],
    values: &[&[T; N]],
    out: &mut Vec<Column>,
) {
    for (i, name) in names.iter().enumerate() {
        let axis: Vec<&T> = values.iter().map(|v| &v[i]).collect();
        T::write(prefix, name, &axis, out);
    }
}

/// Read the arrays [`write_axes`] wrote.
pub fn read_axes<T: Columns, const N: usize>(
    prefix: &str,
    names: [&str; N],
    table: &DataFrame,
) -> PolarsResult<Vec<[T; N]>> {
    let mut axes = names
        .iter()
        .map(|name| T::read(prefix, name, table).map(Vec::into_iter))
        .collect::<PolarsResult<Vec<_>>>()?;
    Ok((0..table.height())
        // Every column holds one value per row of its table.
        .map(|_| std::array::from_fn(|i| axes[i].next().expect("a value per row")))
        .collect())
}

/// The names of the columns [`write_axes`] writes.
pub fn axes_names<T: Columns>(prefix: &str, names: &[&str], out: &mut Vec<String>) {
    for name in names {
        T::names(prefix, name, out);
    }
}

/// An optional group's columns: its fields' columns, null in the rows
/// where it is `None`.
pub fn write_optional<T: Columns>(
    prefix: &str,
    name: &str,
    values: &[&Option<T>],
    out: &mut Vec<Column>,
) {
    let present: Vec<&T> = values.iter().filter_map(|v| v.as_ref()).collect();
    let mut columns = Vec::new();
    T::write(prefix, name, &present, &mut columns);
    // Each row's place among the present values; null where it has none.
    let mut next: IdxSize = 0;
    let places: IdxCa = values
        .iter()
        .map(|v| {
            v.as_ref().map(|_| {
                next += 1;
                next - 1
            })
        })
        .collect();
    for column in columns {
        // Every place is one of the present values'.
        out.push(column.take(&places).expect("places within the values"));
    }
}

/// Read an optional group: present in the rows where any of its columns
/// holds a value (a group whose every field is `None` reads as absent).
pub fn read_optional<T: Columns>(
    prefix: &str,
    name: &str,
    table: &DataFrame,
) -> PolarsResult<Vec<Option<T>>> {
    let mut names = Vec::new();
    T::names(prefix, name, &mut names);
    let mut present: BooleanChunked = (0..table.height()).map(|_| false).collect();
    for column in names.iter().filter_map(|n| table.column(n).ok()) {
        present = &present | &column.is_not_null();
    }
    let mut values = T::read(prefix, name, &table.filter(&present)?)?.into_iter();
    Ok(present
        .iter()
        // One value per present row.
        .map(|p| {
            p.unwrap_or(false)
                .then(|| values.next().expect("a value per present row"))
        })
        .collect())
}

pub use crate::kind::Named;

fn missing(column: &Column, row: usize) -> polars::prelude::PolarsError {
    polars_err!(ComputeError: "column {} has no value in row {row}", column.name())
}

fn unnamed(column: &Column, row: usize, text: &str) -> polars::prelude::PolarsError {
    polars_err!(ComputeError: "column {} holds {text:?} in row {row}, which is not one of its names", column.name())
}

/// Required and nullable columns of a polars type, read with `$get`.
macro_rules! primitive {
    ($($t:ty => $get:ident),* $(,)?) => {$(
        impl Cell for $t {
            fn column(name: &str, values: &[&Self]) -> Column {
                Column::new(name.into(), values.iter().map(|v| **v).collect::<Vec<$t>>())
            }
            fn values(column: &Column) -> PolarsResult<Vec<Self>> {
                let values = column.$get()?;
                values.iter().enumerate().map(|(i, v)| v.ok_or_else(|| missing(column, i))).collect()
            }
        }

        impl Cell for Option<$t> {
            fn column(name: &str, values: &[&Self]) -> Column {
                Column::new(name.into(), values.iter().map(|v| **v).collect::<Vec<Option<$t>>>())
            }
            fn values(column: &Column) -> PolarsResult<Vec<Self>> {
                Ok(column.$get()?.iter().collect())
            }
            fn absent() -> Option<Self> {
                Some(None)
            }
        }
    )*};
}

primitive!(u32 => u32, u64 => u64, i32 => i32, i64 => i64, f32 => f32, f64 => f64, bool => bool);

/// Small integers stored as Int32: the fewest polars features (no 8-bit
/// types), read back only when they fit.
macro_rules! small {
    ($($t:ty),* $(,)?) => {$(
        impl Cell for $t {
            fn column(name: &str, values: &[&Self]) -> Column {
                Column::new(name.into(), values.iter().map(|v| i32::from(**v)).collect::<Vec<i32>>())
            }
            fn values(column: &Column) -> PolarsResult<Vec<Self>> {
                let values = column.i32()?;
                values.iter().enumerate().map(|(i, v)| {
                    let v = v.ok_or_else(|| missing(column, i))?;
                    <$t>::try_from(v).map_err(|_| polars_err!(ComputeError: "column {} holds {v} in row {i}, out of range for {}", column.name(), stringify!($t)))
                }).collect()
            }
        }

        impl Cell for Option<$t> {
            fn column(name: &str, values: &[&Self]) -> Column {
                Column::new(name.into(), values.iter().map(|v| v.map(i32::from)).collect::<Vec<Option<i32>>>())
            }
            fn values(column: &Column) -> PolarsResult<Vec<Self>> {
                let values = column.i32()?;
                values.iter().enumerate().map(|(i, v)| v.map(|v| {
                    <$t>::try_from(v).map_err(|_| polars_err!(ComputeError: "column {} holds {v} in row {i}, out of range for {}", column.name(), stringify!($t)))
                }).transpose()).collect()
            }
            fn absent() -> Option<Self> {
                Some(None)
            }
        }
    )*};
}

small!(u8, i8, u16);

/// Counts stored as UInt64, read back where they fit.
impl Cell for usize {
    fn column(name: &str, values: &[&Self]) -> Column {
        Column::new(
            name.into(),
            values.iter().map(|v| **v as u64).collect::<Vec<u64>>(),
        )
    }
    fn values(column: &Column) -> PolarsResult<Vec<Self>> {
        u64::values(column)?
            .into_iter()
            .enumerate()
            .map(|(i, v)| count(column, i, v))
            .collect()
    }
}

impl Cell for Option<usize> {
    fn column(name: &str, values: &[&Self]) -> Column {
        let counts = values.iter().map(|v| v.map(|v| v as u64));
        Column::new(name.into(), counts.collect::<Vec<Option<u64>>>())
    }
    fn values(column: &Column) -> PolarsResult<Vec<Self>> {
        let values = <Option<u64>>::values(column)?;
        values
            .into_iter()
            .enumerate()
            .map(|(i, v)| v.map(|v| count(column, i, v)).transpose())
            .collect()
    }
    fn absent() -> Option<Self> {
        Some(None)
    }
}

fn count(column: &Column, row: usize, value: u64) -> PolarsResult<usize> {
    usize::try_from(value).map_err(
        |_| polars_err!(ComputeError: "column {} holds {value} in row {row}, too many to count", column.name()),
    )
}

impl Cell for String {
    fn column(name: &str, values: &[&Self]) -> Column {
        Column::new(
            name.into(),
            values.iter().map(|v| v.as_str()).collect::<Vec<&str>>(),
        )
    }
    fn values(column: &Column) -> PolarsResult<Vec<Self>> {
        let values = column.str()?;
        values
            .iter()
            .enumerate()
            .map(|(i, v)| v.map(str::to_string).ok_or_else(|| missing(column, i)))
            .collect()
    }
}

impl Cell for Option<String> {
    fn column(name: &str, values: &[&Self]) -> Column {
        Column::new(
            name.into(),
            values
                .iter()
                .map(|v| v.as_deref())
                .collect::<Vec<Option<&str>>>(),
        )
    }
    fn values(column: &Column) -> PolarsResult<Vec<Self>> {
        Ok(column
            .str()?
            .iter()
            .map(|v| v.map(str::to_string))
            .collect())
    }
    fn absent() -> Option<Self> {
        Some(None)
    }
}

impl<T: Named> Cell for T {
    fn column(name: &str, values: &[&Self]) -> Column {
        Column::new(
            name.into(),
            values.iter().map(|v| v.name()).collect::<Vec<&str>>(),
        )
    }
    fn values(column: &Column) -> PolarsResult<Vec<Self>> {
        text_values(column)?
            .into_iter()
            .enumerate()
            .map(|(i, v)| {
                let text = v.ok_or_else(|| missing(column, i))?;
                T::named(text).ok_or_else(|| unnamed(column, i, text))
            })
            .collect()
    }
}

impl<T: Named> Cell for Option<T> {
    fn column(name: &str, values: &[&Self]) -> Column {
        Column::new(
            name.into(),
            values
                .iter()
                .map(|v| v.map(T::name))
                .collect::<Vec<Option<&str>>>(),
        )
    }
    fn values(column: &Column) -> PolarsResult<Vec<Self>> {
        text_values(column)?
            .into_iter()
            .enumerate()
            .map(|(i, v)| {
                v.map(|text| T::named(text).ok_or_else(|| unnamed(column, i, text)))
                    .transpose()
            })
            .collect()
    }
    fn absent() -> Option<Self> {
        Some(None)
    }
}

/// A list of kinds: their names joined by `,` (empty for none).
impl<T: Named> Cell for Vec<T> {
    fn column(name: &str, values: &[&Self]) -> Column {
        let lists = values.iter().map(|kinds| {
            let names: Vec<&str> = kinds.iter().map(|k| k.name()).collect();
            names.join(",")
        });
        Column::new(name.into(), lists.collect::<Vec<String>>())
    }
    fn values(column: &Column) -> PolarsResult<Vec<Self>> {
        text_values(column)?
            .into_iter()
            .enumerate()
            .map(|(i, v)| {
                let list = v.ok_or_else(|| missing(column, i))?;
                list.split(',')
                    .filter(|name| !name.is_empty())
                    .map(|name| T::named(name).ok_or_else(|| unnamed(column, i, name)))
                    .collect()
            })
            .collect()
    }
}

fn text_values(column: &Column) -> PolarsResult<Vec<Option<&str>>> {
    if column.dtype() != &DataType::String {
        return Err(
            polars_err!(SchemaMismatch: "column {} holds {}, not names", column.name(), column.dtype()),
        );
    }
    Ok(column.str()?.iter().collect())
}

/// Declare a table: a row struct whose fields are its columns, in order,
/// and its [`Row`] writer and reader. Every field is public; the struct
/// derives `Debug`, `Clone` and `PartialEq` besides what it names.
///
/// A field is one column named as the field, or a group's columns; after
/// its type, `as` names its columns otherwise:
///
/// - `as width_mm`: the column is `width_mm`;
/// - `as [x, y, z]`: an array, one column per element;
/// - `as "best_"`: a group whose columns are named after `best_`;
/// - `as ?`: an optional group (`Option<G>`), its columns null where it is
///   `None`;
/// - `as _`: not a column (read back as its `Default`).
///
/// ```
/// postflight_core::table! {
///     /// One fix of `gnss.parquet`.
///     pub struct Fix {
///         /// Nanoseconds.
///         time_ns: i64,
///         /// Latitude, longitude.
///         place: [f64; 2] as [latitude_deg, longitude_deg],
///         status: Option<i8> as fix_status,
///         note: String as _,
///     }
/// }
/// use postflight_core::table::Row;
/// let rows = vec![Fix { time_ns: 1, place: [47.5, 8.5], status: Some(2), note: String::new() }];
/// let table = Fix::frame(&rows).unwrap();
/// assert_eq!(Fix::column_names(), ["time_ns", "latitude_deg", "longitude_deg", "fix_status"]);
/// assert_eq!(Fix::rows(&table).unwrap(), rows);
/// ```
#[macro_export]
macro_rules! table {
    (
        $(#[$meta:meta])*
        $vis:vis struct $name:ident {
            $( $(#[$field_meta:meta])* $field:ident : $ty:ty $(as $columns:tt)? ),* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, PartialEq)]
        $vis struct $name {
            $( $(#[$field_meta])* pub $field: $ty, )*
        }

        impl $crate::table::Columns for $name {
            fn write(
                prefix: &str,
                _: &str,
                rows: &[&Self],
                out: &mut ::std::vec::Vec<$crate::table::Column>,
            ) {
                $(
                    let values: ::std::vec::Vec<&$ty> = rows.iter().map(|r| &r.$field).collect();
                    $crate::__table_field!(write prefix values out $field $ty $(, $columns)?);
                )*
            }

            fn read(
                prefix: &str,
                _: &str,
                table: &$crate::table::DataFrame,
            ) -> $crate::table::PolarsResult<::std::vec::Vec<Self>> {
                $(
                    let mut $field = {
                        let values: ::std::vec::Vec<$ty> =
                            $crate::__table_field!(read prefix table $field $ty $(, $columns)?);
                        values.into_iter()
                    };
                )*
                Ok((0..table.height())
                    .map(|_| Self {
                        // Every column holds one value per row of its table.
                        $( $field: $field.next().expect("a value per row"), )*
                    })
                    .collect())
            }

            fn names(prefix: &str, _: &str, out: &mut ::std::vec::Vec<::std::string::String>) {
                $( $crate::__table_field!(names prefix out $field $ty $(, $columns)?); )*
            }
        }

        impl $crate::table::Row for $name {}
    };
}

/// One field of a [`table!`]: its columns written, read or named, by the
/// form of its `as`.
#[doc(hidden)]
#[macro_export]
macro_rules! __table_field {
    (write $prefix:ident $values:ident $out:ident $field:ident $ty:ty) => {
        <$ty as $crate::table::Columns>::write($prefix, stringify!($field), &$values, $out)
    };
    (write $prefix:ident $values:ident $out:ident $field:ident $ty:ty, _) => {
        let _ = $values;
    };
    (write $prefix:ident $values:ident $out:ident $field:ident $ty:ty, ?) => {
        $crate::table::write_optional($prefix, "", &$values, $out)
    };
    (write $prefix:ident $values:ident $out:ident $field:ident $ty:ty, [$($axis:ident),+ $(,)?]) => {
        $crate::table::write_axes($prefix, [$(stringify!($axis)),+], &$values, $out)
    };
    (write $prefix:ident $values:ident $out:ident $field:ident $ty:ty, $group:literal) => {
        <$ty as $crate::table::Columns>::write(&format!("{}{}", $prefix, $group), "", &$values, $out)
    };
    (write $prefix:ident $values:ident $out:ident $field:ident $ty:ty, $column:ident) => {
        <$ty as $crate::table::Columns>::write($prefix, stringify!($column), &$values, $out)
    };

    (read $prefix:ident $table:ident $field:ident $ty:ty) => {
        <$ty as $crate::table::Columns>::read($prefix, stringify!($field), $table)?
    };
    (read $prefix:ident $table:ident $field:ident $ty:ty, _) => {
        (0..$table.height()).map(|_| ::std::default::Default::default()).collect()
    };
    (read $prefix:ident $table:ident $field:ident $ty:ty, ?) => {
        $crate::table::read_optional($prefix, "", $table)?
    };
    (read $prefix:ident $table:ident $field:ident $ty:ty, [$($axis:ident),+ $(,)?]) => {
        $crate::table::read_axes($prefix, [$(stringify!($axis)),+], $table)?
    };
    (read $prefix:ident $table:ident $field:ident $ty:ty, $group:literal) => {
        <$ty as $crate::table::Columns>::read(&format!("{}{}", $prefix, $group), "", $table)?
    };
    (read $prefix:ident $table:ident $field:ident $ty:ty, $column:ident) => {
        <$ty as $crate::table::Columns>::read($prefix, stringify!($column), $table)?
    };

    (names $prefix:ident $out:ident $field:ident $ty:ty) => {
        <$ty as $crate::table::Columns>::names($prefix, stringify!($field), $out)
    };
    (names $prefix:ident $out:ident $field:ident $ty:ty, _) => {};
    (names $prefix:ident $out:ident $field:ident $ty:ty, ?) => {
        <<$ty as $crate::table::Optional>::Group as $crate::table::Columns>::names($prefix, "", $out)
    };
    (names $prefix:ident $out:ident $field:ident $ty:ty, [$($axis:ident),+ $(,)?]) => {
        $crate::table::axes_names::<<$ty as $crate::table::Axes>::Element>(
            $prefix,
            &[$(stringify!($axis)),+],
            $out,
        )
    };
    (names $prefix:ident $out:ident $field:ident $ty:ty, $group:literal) => {
        <$ty as $crate::table::Columns>::names(&format!("{}{}", $prefix, $group), "", $out)
    };
    (names $prefix:ident $out:ident $field:ident $ty:ty, $column:ident) => {
        <$ty as $crate::table::Columns>::names($prefix, stringify!($column), $out)
    };
}

/// An optional group's type, `Option<G>`: names its group for [`table!`].
pub trait Optional {
    type Group: Columns;
}

impl<T: Columns> Optional for Option<T> {
    type Group = T;
}

/// An array's type: names its element for [`table!`].
pub trait Axes {
    type Element: Columns;
}

impl<T: Columns, const N: usize> Axes for [T; N] {
    type Element = T;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::FaceSide;

    crate::table! {
        struct Inner {
            a: u32,
            b: Option<String>,
        }
    }

    crate::table! {
        struct Outer {
            face: FaceSide,
            inner: Inner,
            faces: Vec<FaceSide>,
            small: Option<u8>,
        }
    }

    #[test]
    fn rows_round_trip_through_their_columns() {
        let rows = vec![
            Outer {
                face: FaceSide::PosX,
                inner: Inner { a: 1, b: None },
                faces: vec![],
                small: Some(5),
            },
            Outer {
                face: FaceSide::NegZ,
                inner: Inner {
                    a: 2,
                    b: Some("pier 1".into()),
                },
                faces: vec![FaceSide::NegX, FaceSide::PosY],
                small: None,
            },
        ];
        let table = Outer::frame(&rows).unwrap();
        assert_eq!(Outer::column_names(), ["face", "a", "b", "faces", "small"]);
        let names: Vec<&str> = table
            .get_column_names()
            .iter()
            .map(|n| n.as_str())
            .collect();
        assert_eq!(names, Outer::column_names());
        assert_eq!(Outer::rows(&table).unwrap(), rows);
        // A nullable column a table was written without reads as empty.
        let old = table.drop("b").unwrap();
        assert_eq!(Outer::rows(&old).unwrap()[1].inner.b, None);
        let e = Outer::rows(&table.drop("a").unwrap()).unwrap_err();
        assert!(e.to_string().contains("a"), "{e}");
    }

    #[test]
    fn a_value_that_is_not_what_its_column_declares_names_column_and_row() {
        let table = polars::df!(
            "face" => ["+x", "up"], "a" => [1u32, 2], "faces" => ["", ""], "small" => [1i32, 300]
        )
        .unwrap();
        let e = Outer::rows(&table).unwrap_err().to_string();
        assert!(
            e.contains("column face holds \"up\" in row 1, which is not one of its names"),
            "{e}"
        );
        let table = polars::df!(
            "face" => ["+x", "-x"], "a" => [1u32, 2], "faces" => ["", ""], "small" => [1i32, 300]
        )
        .unwrap();
        let e = Outer::rows(&table).unwrap_err().to_string();
        assert!(e.contains("column small holds 300 in row 1"), "{e}");
        let table = polars::df!(
            "face" => [Some("+x"), None], "a" => [1u32, 2], "faces" => ["", ""], "small" => [1i32, 3]
        )
        .unwrap();
        let e = Outer::rows(&table).unwrap_err().to_string();
        assert!(e.contains("column face has no value in row 1"), "{e}");
    }

    crate::table! {
        struct Renamed {
            at: [i32; 2] as [at_x, at_y],
            best: Inner as "best_",
            width: Option<Inner> as ?,
            kind: FaceSide as face,
            note: String as _,
        }
    }

    #[test]
    fn fields_name_their_columns_as_declared() {
        let rows = vec![
            Renamed {
                at: [1, -2],
                best: Inner { a: 7, b: None },
                width: Some(Inner { a: 3, b: None }),
                kind: FaceSide::PosZ,
                note: String::new(),
            },
            Renamed {
                at: [3, 4],
                best: Inner {
                    a: 8,
                    b: Some("x".into()),
                },
                width: None,
                kind: FaceSide::NegY,
                note: String::new(),
            },
        ];
        let table = Renamed::frame(&rows).unwrap();
        assert_eq!(
            Renamed::column_names(),
            ["at_x", "at_y", "best_a", "best_b", "a", "b", "face"]
        );
        // An absent group is null in each of its columns.
        assert_eq!(table.column("a").unwrap().null_count(), 1);
        assert_eq!(Renamed::rows(&table).unwrap(), rows);
        // A skipped field reads as its default.
        let mut noted = rows.clone();
        noted[0].note = "not a column".into();
        assert_eq!(
            Renamed::rows(&Renamed::frame(&noted).unwrap()).unwrap(),
            rows
        );
    }
}
