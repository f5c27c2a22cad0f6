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

pub use polars::prelude::{Column, DataFrame, PolarsResult};
use polars::prelude::{DataType, polars_err};

/// Values that make columns of a table: one column (a [`Cell`]) or a
/// row's several (a [`table!`] type).
pub trait Columns: Sized {
    /// Append the columns of `values`, the field `name` of each row.
    fn write(name: &'static str, values: &[&Self], out: &mut Vec<Column>);
    /// Read them back from `table`, one value per row.
    fn read(name: &'static str, table: &DataFrame) -> PolarsResult<Vec<Self>>;
    /// Append the names of the columns it makes.
    fn names(name: &'static str, out: &mut Vec<&'static str>);
}

/// A row type made by [`table!`]: a whole table's columns.
pub trait Row: Columns {
    /// The table of `rows`.
    fn frame(rows: &[Self]) -> PolarsResult<DataFrame> {
        let refs: Vec<&Self> = rows.iter().collect();
        let mut columns = Vec::new();
        Self::write("", &refs, &mut columns);
        DataFrame::new(rows.len(), columns)
    }

    /// The rows of `table`; an error names the column (and row) that does
    /// not hold what the row type declares.
    fn rows(table: &DataFrame) -> PolarsResult<Vec<Self>> {
        Self::read("", table)
    }

    /// Its columns' names, in order.
    fn column_names() -> Vec<&'static str> {
        let mut names = Vec::new();
        Self::names("", &mut names);
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
    fn write(name: &'static str, values: &[&Self], out: &mut Vec<Column>) {
        out.push(T::column(name, values));
    }

    fn read(name: &'static str, table: &DataFrame) -> PolarsResult<Vec<Self>> {
        match (table.column(name), T::absent()) {
            (Ok(column), _) => T::values(column),
            (Err(_), Some(_)) => Ok((0..table.height()).filter_map(|_| T::absent()).collect()),
            (Err(e), None) => Err(e),
        }
    }

    fn names(name: &'static str, out: &mut Vec<&'static str>) {
        out.push(name);
    }
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
/// ```
/// postflight_core::table! {
///     /// One fix of `gnss.parquet`.
///     pub struct Fix {
///         /// Nanoseconds.
///         time_ns: i64,
///         latitude_deg: f64,
///         status: Option<i8>,
///     }
/// }
/// use postflight_core::table::Row;
/// let rows = vec![Fix { time_ns: 1, latitude_deg: 47.5, status: Some(2) }];
/// let table = Fix::frame(&rows).unwrap();
/// assert_eq!(Fix::column_names(), ["time_ns", "latitude_deg", "status"]);
/// assert_eq!(Fix::rows(&table).unwrap(), rows);
/// ```
#[macro_export]
macro_rules! table {
    (
        $(#[$meta:meta])*
        $vis:vis struct $name:ident {
            $( $(#[$field_meta:meta])* $field:ident : $ty:ty ),* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, PartialEq)]
        $vis struct $name {
            $( $(#[$field_meta])* pub $field: $ty, )*
        }

        impl $crate::table::Columns for $name {
            fn write(
                _: &'static str,
                rows: &[&Self],
                out: &mut ::std::vec::Vec<$crate::table::Column>,
            ) {
                $(
                    let values: ::std::vec::Vec<&$ty> = rows.iter().map(|r| &r.$field).collect();
                    <$ty as $crate::table::Columns>::write(stringify!($field), &values, out);
                )*
            }

            fn read(
                _: &'static str,
                table: &$crate::table::DataFrame,
            ) -> $crate::table::PolarsResult<::std::vec::Vec<Self>> {
                $(
                    let mut $field =
                        <$ty as $crate::table::Columns>::read(stringify!($field), table)?.into_iter();
                )*
                Ok((0..table.height())
                    .map(|_| Self {
                        // Every column holds one value per row of its table.
                        $( $field: $field.next().expect("a value per row"), )*
                    })
                    .collect())
            }

            fn names(_: &'static str, out: &mut ::std::vec::Vec<&'static str>) {
                $( <$ty as $crate::table::Columns>::names(stringify!($field), out); )*
            }
        }

        impl $crate::table::Row for $name {}
    };
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
}
