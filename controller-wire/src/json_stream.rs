//! AUBO ARCS JSON-RPC frames nothing: requests and replies are bare JSON
//! objects, concatenated with no delimiter (whitespace between them is
//! tolerated), so each side parses its byte stream incrementally.

use serde_json::Value;

/// Incremental parser of concatenated JSON values in a byte stream.
#[derive(Debug, Default)]
pub struct StreamParser {
    buf: Vec<u8>,
}

impl StreamParser {
    /// Appends received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.buf.extend_from_slice(bytes);
    }

    /// The next complete value, `None` if more bytes are needed. On a syntax
    /// error the buffered bytes are discarded (the stream cannot be
    /// resynchronised) and the error returned.
    pub fn next_value(&mut self) -> Result<Option<Value>, serde_json::Error> {
        let mut it = serde_json::Deserializer::from_slice(&self.buf).into_iter::<Value>();
        match it.next() {
            None => {
                self.buf.clear();
                Ok(None)
            }
            Some(Ok(v)) => {
                let used = it.byte_offset();
                self.buf.drain(..used);
                Ok(Some(v))
            }
            Some(Err(e)) if e.is_eof() => Ok(None),
            Some(Err(e)) => {
                self.buf.clear();
                Err(e)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parser_splits_concatenated_objects_at_any_boundary() {
        let text = br#"{"id":1,"m":"a"}  {"id":2,"p":[1,2,{"x":"}"}]}
{"id":3}"#;
        for cut in 0..text.len() {
            let mut p = StreamParser::default();
            let mut ids = Vec::new();
            for part in [&text[..cut], &text[cut..]] {
                p.push(part);
                while let Some(v) = p.next_value().unwrap() {
                    ids.push(v["id"].as_i64().unwrap());
                }
            }
            assert_eq!(ids, vec![1, 2, 3], "cut at {cut}");
        }
    }

    #[test]
    fn parser_reports_garbage_and_recovers() {
        let mut p = StreamParser::default();
        p.push(b"{\"id\":1]");
        assert!(p.next_value().is_err());
        p.push(b"{\"id\":4}");
        assert_eq!(p.next_value().unwrap().unwrap()["id"], 4);
    }
}
