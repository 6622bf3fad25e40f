//! Time-series CSV tables (`joints.csv`, `imu.csv`, `tracker.csv`; docs/model.md §7).
//!
//! A table is a header naming its required columns first (extra columns after
//! them are allowed and ignored, unless asked for by name as *optional*
//! columns: [`read_table_with`]), then one row per sample in time order.
//! Lines starting with `#` are comments. Every value must be a finite number;
//! time must never decrease. Errors name the file and the line.
//!
//! The files are read as the `csv` crate reads them (fields trimmed, `"`
//! quotes, `\r\n` line ends, its line numbers) and every number as
//! `str::parse::<f64>` reads it, without either on the common path:
//! `records` splits the stream into records through one reused buffer,
//! `decimal` reads plain numbers straight from the bytes, `read` puts
//! the rows together and names the problem of a bad one.

mod decimal;
mod read;
mod records;
#[cfg(test)]
mod reference;

use std::path::Path;

use records::Records;

use super::SessionError;

/// A time-ordered table of samples with a fixed number of value columns.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Table {
    /// Column names of the values (without `t`), as in the header.
    pub columns: Vec<String>,
    /// Sample times, seconds, non-decreasing.
    pub t: Vec<f64>,
    /// Values, row-major: row `i` is `values[i * width .. (i + 1) * width]`.
    pub values: Vec<f64>,
}

impl Table {
    /// Number of value columns.
    pub fn width(&self) -> usize {
        self.columns.len()
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Whether the table has no rows.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Row `i` of the values.
    ///
    /// # Panics
    /// If `i >= self.len()`.
    #[track_caller]
    pub fn row(&self, i: usize) -> &[f64] {
        let w = self.width();
        &self.values[i * w..(i + 1) * w]
    }

    /// Time span `(first, last)` of the rows, or `None` when empty.
    pub fn span(&self) -> Option<(f64, f64)> {
        Some((*self.t.first()?, *self.t.last()?))
    }

    /// The sample rate, Hz, of the median interval between rows (to 1 mHz:
    /// times written in decimal carry rounding); `None` without an interval.
    pub fn median_rate(&self) -> Option<f64> {
        let mut dt: Vec<f64> = self
            .t
            .windows(2)
            .map(|w| w[1] - w[0])
            .filter(|d| *d > 0.0)
            .collect();
        if dt.is_empty() {
            return None;
        }
        dt.sort_by(f64::total_cmp);
        Some((1000.0 / dt[dt.len() / 2]).round() / 1000.0)
    }
}

/// Which value columns a table must start with.
#[derive(Debug, Clone, Copy)]
pub enum Columns<'a> {
    /// Exactly these names, in this order, after `t`.
    Fixed(&'a [&'a str]),
    /// `q1, q2, …` — as many as the header has, at least one.
    Joints,
}

/// Read a table from `path`. See the module doc for the rules.
pub fn read_table(path: &Path, columns: Columns<'_>) -> Result<Table, SessionError> {
    read_table_with(path, columns, &[]).map(|(t, _)| t)
}

/// Parse a table from any reader; `path` is only used in error messages.
pub fn parse_table(
    reader: impl std::io::Read,
    path: &Path,
    columns: Columns<'_>,
) -> Result<Table, SessionError> {
    parse_table_with(reader, path, columns, &[]).map(|(t, _)| t)
}

/// Values of optional extra columns, one entry per name asked for: `None`
/// when the header does not have it, else one value per row.
pub type OptionalColumns = Vec<Option<Vec<f64>>>;

/// [`read_table`], also reading the extra columns named `optional` when the
/// header has them after the required ones (e.g. `temp_c` of `imu.csv`).
/// A column that is present must hold a finite number on every row.
pub fn read_table_with(
    path: &Path,
    columns: Columns<'_>,
    optional: &[&str],
) -> Result<(Table, OptionalColumns), SessionError> {
    let file = std::fs::File::open(path).map_err(|e| SessionError::io(path, e))?;
    let size = file.metadata().map_or(0, |m| m.len());
    read::table(Records::new(file), size, path, columns, optional)
}

/// [`parse_table`] with optional extra columns (see [`read_table_with`]).
pub fn parse_table_with(
    reader: impl std::io::Read,
    path: &Path,
    columns: Columns<'_>,
    optional: &[&str],
) -> Result<(Table, OptionalColumns), SessionError> {
    read::table(Records::new(reader), 0, path, columns, optional)
}

/// The required columns' names, or why `header` lacks them.
fn required_columns(header: &[String], columns: Columns<'_>) -> Result<Vec<String>, String> {
    let got: Vec<&str> = header.iter().map(String::as_str).collect();
    if got.first() != Some(&"t") {
        return Err(format!(
            "the header must start with `t`, found `{}`",
            got.first().copied().unwrap_or("")
        ));
    }
    match columns {
        Columns::Fixed(names) => {
            for (i, name) in names.iter().enumerate() {
                match got.get(i + 1) {
                    Some(g) if g == name => {}
                    Some(g) => {
                        return Err(format!(
                            "column {} must be `{name}`, found `{g}` (expected header `t,{}`)",
                            i + 2,
                            names.join(",")
                        ))
                    }
                    None => {
                        return Err(format!(
                            "missing column `{name}` (expected header `t,{}`)",
                            names.join(",")
                        ))
                    }
                }
            }
            Ok(names.iter().map(|s| s.to_string()).collect())
        }
        Columns::Joints => {
            let n = got[1..]
                .iter()
                .enumerate()
                .take_while(|(i, g)| **g == format!("q{}", i + 1))
                .count();
            if n == 0 {
                return Err("missing joint columns: expected header `t,q1,q2,…`".into());
            }
            Ok((1..=n).map(|i| format!("q{i}")).collect())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str, columns: Columns<'_>) -> Result<Table, SessionError> {
        parse_table(text.as_bytes(), Path::new("x.csv"), columns)
    }

    #[test]
    fn reads_joint_table_with_comments_and_extra_columns() {
        let t = parse(
            "# recorded by hand\nt,q1,q2,extra\n0.0,1,2,zz\n# mid comment\n0.5, 3 ,4,\n",
            Columns::Joints,
        )
        .unwrap();
        assert_eq!(t.columns, ["q1", "q2"]);
        assert_eq!(t.t, [0.0, 0.5]);
        assert_eq!(t.row(1), [3.0, 4.0]);
    }

    #[test]
    fn errors_name_file_and_line() {
        let e = parse("t,ax\n0,1\n1,nan\n", Columns::Fixed(&["ax"])).unwrap_err();
        assert_eq!(
            e.to_string(),
            "x.csv:3: column `ax`: nan is not a finite number"
        );
        let e = parse("t,ax\n0,1\n1,abc\n", Columns::Fixed(&["ax"])).unwrap_err();
        assert_eq!(e.to_string(), "x.csv:3: column `ax`: `abc` is not a number");
        let e = parse("t,ax\n0,1\n-1,2\n", Columns::Fixed(&["ax"])).unwrap_err();
        assert_eq!(
            e.to_string(),
            "x.csv:3: time goes backwards: t = -1 after t = 0"
        );
        let e = parse("t,ax,ay\n0,1,2\n1,2\n", Columns::Fixed(&["ax", "ay"])).unwrap_err();
        assert_eq!(
            e.to_string(),
            "x.csv:3: expected at least 3 fields, found 2"
        );
    }

    #[test]
    fn header_problems_are_reported() {
        let e = parse("t,ax,gy\n", Columns::Fixed(&["ax", "ay"])).unwrap_err();
        assert!(
            e.to_string().contains("column 3 must be `ay`, found `gy`"),
            "{e}"
        );
        let e = parse("t,ax\n", Columns::Fixed(&["ax", "ay"])).unwrap_err();
        assert!(e.to_string().contains("missing column `ay`"), "{e}");
        let e = parse("time,q1\n0,0\n", Columns::Joints).unwrap_err();
        assert!(e.to_string().contains("must start with `t`"), "{e}");
        let e = parse("t,a1\n0,0\n", Columns::Joints).unwrap_err();
        assert!(e.to_string().contains("missing joint columns"), "{e}");
        let e = parse("", Columns::Joints).unwrap_err();
        assert!(e.to_string().contains("empty"), "{e}");
        let e = parse("t,q1\n", Columns::Joints).unwrap_err();
        assert!(e.to_string().contains("no data rows"), "{e}");
    }

    /// Optional columns are found by name after the required ones, read
    /// when present, `None` when absent, and checked like the others.
    #[test]
    fn optional_columns_are_read_when_present() {
        let text = "t,ax,seq,temp_c\n0,1,7,25.5\n1,2,8,-3\n";
        let (t, extra) = parse_table_with(
            text.as_bytes(),
            Path::new("x.csv"),
            Columns::Fixed(&["ax"]),
            &["temp_c", "humidity"],
        )
        .unwrap();
        assert_eq!(t.values, [1.0, 2.0]);
        assert_eq!(extra, [Some(vec![25.5, -3.0]), None]);
        // a required column is never taken for an optional one
        let (_, extra) = parse_table_with(
            "t,ax\n0,1\n".as_bytes(),
            Path::new("x.csv"),
            Columns::Fixed(&["ax"]),
            &["ax"],
        )
        .unwrap();
        assert_eq!(extra, [None]);
        let e = parse_table_with(
            "t,ax,temp_c\n0,1,20\n1,2,\n".as_bytes(),
            Path::new("x.csv"),
            Columns::Fixed(&["ax"]),
            &["temp_c"],
        )
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "x.csv:3: column `temp_c`: `` is not a finite number"
        );
    }

    #[test]
    fn invalid_utf8_is_an_error_not_a_panic() {
        let bytes = b"t,q1\n0,\xff\xfe\n";
        let e = parse_table(&bytes[..], Path::new("x.csv"), Columns::Joints).unwrap_err();
        assert!(e.to_string().starts_with("x.csv:2:"), "{e}");
    }
}
