//! The table reader before `records` and `decimal` (the `csv` crate's
//! `StringRecord`s, trimmed, parsed by `str::parse`), kept as the reference
//! the tests hold the reader to: the same values bit for bit, the same
//! errors.

use std::path::Path;

use super::{Columns, OptionalColumns, Table};
use crate::SessionError;

/// The table of `reader` as the reader before read it.
pub(super) fn parse_table_with(
    reader: impl std::io::Read,
    path: &Path,
    columns: Columns<'_>,
    optional: &[&str],
) -> Result<(Table, OptionalColumns), SessionError> {
    let mut rdr = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .has_headers(true)
        .flexible(true)
        .from_reader(reader);
    let header = rdr.headers().map_err(|e| csv_error(path, e))?.clone();
    if header.is_empty() || header.iter().all(str::is_empty) {
        return Err(SessionError::file(
            path,
            "the file is empty (no header line)",
        ));
    }
    // the header rule is the reader's own: the reference is for the values
    let header_names: Vec<String> = header.iter().map(str::to_string).collect();
    let names = super::required_columns(&header_names, columns)
        .map_err(|m| SessionError::line(path, header_line(&header), m))?;
    let width = names.len();
    // the field index of each optional column, when the header has it
    let wanted: Vec<Option<usize>> = optional
        .iter()
        .map(|name| {
            header
                .iter()
                .skip(width + 1)
                .position(|h| h == *name)
                .map(|p| p + width + 1)
        })
        .collect();
    let mut extra: OptionalColumns = wanted.iter().map(|w| w.map(|_| Vec::new())).collect();
    let mut table = Table {
        columns: names,
        ..Table::default()
    };
    let mut record = csv::StringRecord::new();
    loop {
        match rdr.read_record(&mut record) {
            Ok(true) => {}
            Ok(false) => break,
            Err(e) => return Err(csv_error(path, e)),
        }
        let line = record.position().map_or(0, |p| p.line());
        if record.len() < width + 1 {
            return Err(SessionError::line(
                path,
                line,
                format!(
                    "expected at least {} fields, found {}",
                    width + 1,
                    record.len()
                ),
            ));
        }
        for (k, field) in record.iter().take(width + 1).enumerate() {
            let v: f64 = field.parse().map_err(|_| {
                let col = if k == 0 { "t" } else { &table.columns[k - 1] };
                SessionError::line(
                    path,
                    line,
                    format!("column `{col}`: `{field}` is not a number"),
                )
            })?;
            if !v.is_finite() {
                let col = if k == 0 { "t" } else { &table.columns[k - 1] };
                return Err(SessionError::line(
                    path,
                    line,
                    format!("column `{col}`: {field} is not a finite number"),
                ));
            }
            if k == 0 {
                if let Some(&prev) = table.t.last() {
                    if v < prev {
                        return Err(SessionError::line(
                            path,
                            line,
                            format!("time goes backwards: t = {v} after t = {prev}"),
                        ));
                    }
                }
                table.t.push(v);
            } else {
                table.values.push(v);
            }
        }
        for ((k, name), values) in wanted.iter().zip(optional).zip(&mut extra) {
            let (Some(k), Some(values)) = (k, values) else {
                continue;
            };
            let field = record.get(*k).unwrap_or("");
            match field.parse::<f64>() {
                Ok(v) if v.is_finite() => values.push(v),
                _ => {
                    return Err(SessionError::line(
                        path,
                        line,
                        format!("column `{name}`: `{field}` is not a finite number"),
                    ))
                }
            }
        }
    }
    if table.is_empty() {
        return Err(SessionError::file(path, "no data rows after the header"));
    }
    Ok((table, extra))
}

fn header_line(header: &csv::StringRecord) -> u64 {
    header.position().map_or(1, |p| p.line())
}

fn csv_error(path: &Path, e: csv::Error) -> SessionError {
    let line = e.position().map(|p| p.line());
    let message = match e.kind() {
        csv::ErrorKind::Utf8 { .. } => "the line is not valid UTF-8".to_string(),
        csv::ErrorKind::Io(_) => e.to_string(),
        _ => e.to_string(),
    };
    match (e.into_kind(), line) {
        (csv::ErrorKind::Io(io), _) => SessionError::io(path, io),
        (_, Some(line)) => SessionError::line(path, line, message),
        (_, None) => SessionError::file(path, message),
    }
}
