//! Text files as UTF-8, a bad byte named by its line, column and offset.

pub(crate) use robimu_model::text::utf8;

/// The text of the file `path`; bytes that are not UTF-8 are refused at
/// their line (the reader's error names the file, line and byte offset).
pub(crate) fn read(path: &std::path::Path) -> Result<String, crate::SessionError> {
    let bytes = std::fs::read(path).map_err(|e| crate::SessionError::io(path, e))?;
    match utf8(&bytes) {
        Ok(_) => Ok(String::from_utf8(bytes).unwrap_or_default()),
        Err(e) => Err(crate::SessionError::line(
            path,
            e.line as u64,
            e.to_string(),
        )),
    }
}
