//! CSV tables written beside the figures: one file, one header, rows of
//! numbers; failures as [`ReportError::Io`] naming the file.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::html::ReportError;

/// A CSV file being written.
pub(crate) struct CsvFile {
    path: PathBuf,
    out: BufWriter<File>,
}

impl CsvFile {
    /// Creates `path` and writes `header` as its first line.
    pub fn create(path: &Path, header: &str) -> Result<Self, ReportError> {
        let file = File::create(path).map_err(|source| io(path, source))?;
        let mut f = Self {
            path: path.to_path_buf(),
            out: BufWriter::new(file),
        };
        f.line(header)?;
        Ok(f)
    }

    /// Writes one line.
    pub fn line(&mut self, line: &str) -> Result<(), ReportError> {
        writeln!(self.out, "{line}").map_err(|source| io(&self.path, source))
    }

    /// Writes the rest and closes the file.
    pub fn finish(mut self) -> Result<(), ReportError> {
        self.out.flush().map_err(|source| io(&self.path, source))
    }
}

/// Writes `path`: `header`, then `lines`.
pub fn write_csv(
    path: &Path,
    header: &str,
    lines: impl IntoIterator<Item = String>,
) -> Result<(), ReportError> {
    let mut f = CsvFile::create(path, header)?;
    for line in lines {
        f.line(&line)?;
    }
    f.finish()
}

fn io(path: &Path, source: std::io::Error) -> ReportError {
    ReportError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// `values` in Rust's `{:e}` form, comma-separated.
pub(crate) fn exp_row(values: &[f64]) -> String {
    let cols: Vec<String> = values.iter().map(|v| format!("{v:e}")).collect();
    cols.join(",")
}
