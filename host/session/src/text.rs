//! Text files as UTF-8, a bad byte named by its line, column and offset.

/// Where a file stops being UTF-8.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("not UTF-8 text: invalid byte 0x{byte:02x} at byte offset {offset} (line {line}, column {column})")]
pub(crate) struct NotUtf8 {
    /// The byte.
    pub byte: u8,
    /// Its 0-based offset in the file.
    pub offset: usize,
    /// 1-based line.
    pub line: usize,
    /// 1-based column (in bytes).
    pub column: usize,
}

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

/// `bytes` as UTF-8 text, or where it is not.
pub(crate) fn utf8(bytes: &[u8]) -> Result<&str, NotUtf8> {
    std::str::from_utf8(bytes).map_err(|e| {
        let offset = e.valid_up_to();
        let before = &bytes[..offset];
        let line_start = before
            .iter()
            .rposition(|&b| b == b'\n')
            .map_or(0, |i| i + 1);
        NotUtf8 {
            byte: bytes[offset],
            offset,
            line: 1 + before.iter().filter(|&&b| b == b'\n').count(),
            column: 1 + offset - line_start,
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bad_byte_is_placed() {
        assert_eq!(utf8(b"ab\nc").unwrap(), "ab\nc");
        let e = utf8(b"{\n  \"a\": \"x\xffy\"\n}").unwrap_err();
        assert_eq!((e.offset, e.line, e.column, e.byte), (11, 2, 10, 0xff));
        assert!(e.to_string().contains("byte offset 11 (line 2, column 10)"));
    }
}
