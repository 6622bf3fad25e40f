//! Text files as UTF-8, a bad byte named by its line, column and offset
//! (every reader of a text file the user gives: robot descriptions, session
//! and result files, bag metadata, ping logs), instead of the standard
//! library's "stream did not contain valid UTF-8".

use std::path::Path;

/// Where a file stops being UTF-8.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("not UTF-8 text: invalid byte 0x{byte:02x} at byte offset {offset} (line {line}, column {column})")]
pub struct NotUtf8 {
    /// The byte.
    pub byte: u8,
    /// Its 0-based offset in the file.
    pub offset: usize,
    /// 1-based line.
    pub line: usize,
    /// 1-based column (in bytes).
    pub column: usize,
}

/// `bytes` as UTF-8 text, or where it is not.
pub fn utf8(bytes: &[u8]) -> Result<&str, NotUtf8> {
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

/// [`std::fs::read_to_string`] with bytes that are not UTF-8 placed: an
/// error of kind [`std::io::ErrorKind::InvalidData`] whose text is
/// [`NotUtf8`]'s (line, column, byte offset).
pub fn read_to_string(path: impl AsRef<Path>) -> std::io::Result<String> {
    let bytes = std::fs::read(path)?;
    if let Err(e) = utf8(&bytes) {
        return Err(std::io::Error::new(std::io::ErrorKind::InvalidData, e));
    }
    Ok(String::from_utf8(bytes).unwrap_or_default())
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

    #[test]
    fn a_file_that_is_not_utf8_is_refused_with_the_place() {
        let dir = std::env::temp_dir().join(format!("robimu-text-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("t.toml");
        std::fs::write(&p, b"a = 1\nb = \"\xc3\x28\"\n").unwrap();
        let e = read_to_string(&p).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::InvalidData);
        assert_eq!(
            e.to_string(),
            "not UTF-8 text: invalid byte 0xc3 at byte offset 11 (line 2, column 6)"
        );
        std::fs::write(&p, "a = \"é\"\n").unwrap();
        assert_eq!(read_to_string(&p).unwrap(), "a = \"é\"\n");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
