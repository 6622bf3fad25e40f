//! The records of a CSV table, split exactly as the `csv` crate splits them
//! with the table settings (`,` between fields, `"` quotes, `#` comment
//! lines, `\n`, `\r\n` or `\r` ending a record, blank lines skipped, a UTF-8
//! byte-order mark skipped), streamed through one reused buffer. Its quirks
//! are kept too: see the line numbers below, and a last line that is a
//! comment without a line end is a record of one empty field.
//!
//! A record without a `"` (all of robimu's files) is handed out as its bytes,
//! found with one vectorised scan; a record with one is split by `csv-core`,
//! the `csv` crate's own parser. Each record carries the line number the
//! `csv` crate gives it: 1 + the `\n` read before it, where the reading of a
//! record starts right after the previous record's terminating byte (so a
//! record after comment lines, blank lines or a `\r\n` gets the line of the
//! first byte read for it, not its own).

use std::io::Read;

/// The buffer's first size; it grows only for a record longer than it.
const CHUNK: usize = 64 * 1024;

/// One record: its fields, separated by `,` or split by `csv-core`.
#[derive(Debug, Clone, Copy)]
pub(super) enum Record<'a> {
    /// A record without quotes: its bytes (no terminator), fields separated
    /// by `,`.
    Plain(&'a [u8]),
    /// A record with a `"`, split by `csv-core`: the fields' bytes one after
    /// the other and where each ends.
    Split {
        /// The fields' bytes.
        bytes: &'a [u8],
        /// The end of each field in `bytes`.
        ends: &'a [usize],
    },
}

impl<'a> Record<'a> {
    /// The fields, untrimmed.
    pub(super) fn fields(self) -> Fields<'a> {
        Fields {
            record: self,
            next: 0,
            done: false,
        }
    }

    /// The number of fields.
    pub(super) fn len(self) -> usize {
        match self {
            Record::Plain(bytes) => 1 + memchr::memchr_iter(b',', bytes).count(),
            Record::Split { ends, .. } => ends.len(),
        }
    }
}

/// The fields of a [`Record`].
pub(super) struct Fields<'a> {
    record: Record<'a>,
    /// The next field's first byte (plain) or index (split).
    next: usize,
    done: bool,
}

impl<'a> Iterator for Fields<'a> {
    type Item = &'a [u8];

    fn next(&mut self) -> Option<&'a [u8]> {
        if self.done {
            return None;
        }
        match self.record {
            Record::Plain(bytes) => {
                let rest = &bytes[self.next..];
                match memchr::memchr(b',', rest) {
                    Some(i) => {
                        self.next += i + 1;
                        Some(&rest[..i])
                    }
                    None => {
                        self.done = true;
                        Some(rest)
                    }
                }
            }
            Record::Split { bytes, ends } => {
                let i = self.next;
                let &end = ends.get(i)?;
                let start = if i == 0 { 0 } else { ends[i - 1] };
                self.next += 1;
                Some(&bytes[start..end])
            }
        }
    }
}

/// The records of a CSV stream (see the module doc).
pub(super) struct Records<R> {
    src: R,
    buf: Vec<u8>,
    /// The unread bytes are `buf[pos..end]`.
    pos: usize,
    /// The bytes dropped from the front of `buf` so far.
    dropped: usize,
    end: usize,
    /// Whether `src` has no more bytes.
    eof: bool,
    /// Whether nothing has been read yet (a byte-order mark may come).
    fresh: bool,
    /// 1 + the `\n` read so far.
    line: u64,
    /// The parser of records with quotes (made at the first), with its
    /// output buffers.
    core: Option<Box<csv_core::Reader>>,
    out: Vec<u8>,
    ends: Vec<usize>,
}

impl<R: Read> Records<R> {
    /// Read the records of `src`.
    pub(super) fn new(src: R) -> Self {
        Self {
            src,
            buf: vec![0; CHUNK],
            pos: 0,
            dropped: 0,
            end: 0,
            eof: false,
            fresh: true,
            line: 1,
            core: None,
            out: Vec::new(),
            ends: Vec::new(),
        }
    }

    /// The bytes taken from the stream so far.
    pub(super) fn consumed(&self) -> usize {
        self.dropped + self.pos
    }

    /// The next record and its line (module doc), or `None` at the end.
    pub(super) fn next_record(&mut self) -> std::io::Result<Option<(u64, Record<'_>)>> {
        let line = self.line;
        // skip blank lines and comment lines
        loop {
            if self.pos == self.end && !self.fill()? {
                return Ok(None);
            }
            match self.buf[self.pos] {
                b'\n' => {
                    self.line += 1;
                    self.pos += 1;
                }
                b'\r' => self.pos += 1,
                b'#' => loop {
                    if let Some(i) = memchr::memchr(b'\n', &self.buf[self.pos..self.end]) {
                        self.pos += i + 1;
                        self.line += 1;
                        break;
                    }
                    self.pos = self.end;
                    if !self.fill()? {
                        // as csv-core: a comment cut by the end of the file
                        // ends in a record of one empty field
                        return Ok(Some((line, Record::Plain(&[]))));
                    }
                },
                _ => break,
            }
        }
        // the record ends at the first `\n` or `\r`, unless a `"` comes first
        let mut scanned = 0;
        loop {
            let rest = &self.buf[self.pos + scanned..self.end];
            match memchr::memchr3(b'\n', b'\r', b'"', rest) {
                Some(i) if rest[i] == b'"' => return self.split(line).map(Some),
                Some(i) => {
                    let (start, stop) = (self.pos, self.pos + scanned + i);
                    self.line += u64::from(self.buf[stop] == b'\n');
                    self.pos = stop + 1;
                    return Ok(Some((line, Record::Plain(&self.buf[start..stop]))));
                }
                None => {
                    scanned = self.end - self.pos;
                    if !self.fill()? {
                        let start = self.pos;
                        self.pos = self.end;
                        return Ok(Some((line, Record::Plain(&self.buf[start..self.end]))));
                    }
                }
            }
        }
    }

    /// The record at `pos`, which has a `"`, split by `csv-core`.
    fn split(&mut self, line: u64) -> std::io::Result<(u64, Record<'_>)> {
        use csv_core::ReadRecordResult as R;
        let core = self.core.get_or_insert_with(|| {
            let mut core = csv_core::ReaderBuilder::new().comment(Some(b'#')).build();
            // it strips a byte-order mark on its first read: that is done at
            // the start of the stream only, never at a quoted record
            let _ = core.read_record(b"", &mut [], &mut []);
            Box::new(core)
        });
        if self.out.is_empty() {
            self.out.resize(256, 0);
            self.ends.resize(16, 0);
        }
        let lines_before = core.line();
        let (mut nout, mut nend) = (0, 0);
        loop {
            let core = self.core.as_mut().expect("made above");
            let (res, nin, o, e) = core.read_record(
                &self.buf[self.pos..self.end],
                &mut self.out[nout..],
                &mut self.ends[nend..],
            );
            self.pos += nin;
            nout += o;
            nend += e;
            match res {
                R::InputEmpty => {
                    self.fill()?;
                }
                R::OutputFull => self.out.resize(2 * self.out.len(), 0),
                R::OutputEndsFull => self.ends.resize(2 * self.ends.len(), 0),
                // a record starts at `pos`: `End` cannot come before it
                R::Record | R::End => {
                    self.line += core.line() - lines_before;
                    let record = Record::Split {
                        bytes: &self.out[..nout],
                        ends: &self.ends[..nend],
                    };
                    return Ok((line, record));
                }
            }
        }
    }

    /// Read more bytes after the unread ones; `false` at the end of the
    /// stream.
    fn fill(&mut self) -> std::io::Result<bool> {
        if self.eof {
            return Ok(false);
        }
        if self.pos > 0 {
            self.buf.copy_within(self.pos..self.end, 0);
            self.end -= self.pos;
            self.dropped += self.pos;
            self.pos = 0;
        }
        if self.end == self.buf.len() {
            self.buf.resize(2 * self.buf.len(), 0);
        }
        let n = loop {
            match self.src.read(&mut self.buf[self.end..]) {
                Ok(n) => break n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        };
        if self.fresh {
            self.fresh = false;
            // as csv-core: a byte-order mark in the first bytes read
            if n >= 3 && self.buf[..3] == *b"\xef\xbb\xbf" {
                self.pos = 3;
            }
        }
        self.end += n;
        self.eof = n == 0;
        Ok(n > 0)
    }
}
