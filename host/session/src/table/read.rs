//! Reading a table: the header, then the rows. A row without quotes whose
//! fields are plain numbers ([`decimal`]) is read straight from its bytes;
//! any other row, and every row with a problem, is read field by field as
//! text, as the `csv` crate's trimmed records were, which names the problem
//! (the messages of the module doc of [`super`]).

use std::path::Path;

use super::records::{Record, Records};
use super::{decimal, Columns, OptionalColumns, Table};
use crate::SessionError;

/// The table of `records`, a stream of `size` bytes (0: unknown).
pub(super) fn table(
    mut records: Records<impl std::io::Read>,
    size: u64,
    path: &Path,
    columns: Columns<'_>,
    optional: &[&str],
) -> Result<(Table, OptionalColumns), SessionError> {
    let io = |e| SessionError::io(path, e);
    let empty = || SessionError::file(path, "the file is empty (no header line)");
    let (line, header) = records.next_record().map_err(io)?.ok_or_else(empty)?;
    let header = text_fields(header).ok_or_else(|| not_utf8(path, line))?;
    if header.iter().all(|h| h.is_empty()) {
        return Err(empty());
    }
    let names =
        super::required_columns(&header, columns).map_err(|m| SessionError::line(path, line, m))?;
    let width = names.len();
    // the field index of each optional column, when the header has it
    let wanted: Vec<Option<usize>> = optional
        .iter()
        .map(|name| {
            header
                .iter()
                .skip(width + 1)
                .position(|h| h == name)
                .map(|p| p + width + 1)
        })
        .collect();
    let mut rows = Rows {
        path,
        table: Table {
            columns: names,
            ..Table::default()
        },
        extra: wanted.iter().map(|w| w.map(|_| Vec::new())).collect(),
        wanted,
        optional,
    };
    let data_start = records.consumed();
    while let Some((line, record)) = records.next_record().map_err(io)? {
        let plain = match record {
            Record::Plain(bytes) => rows.push_plain(bytes),
            Record::Split { .. } => false,
        };
        if !plain {
            rows.push(line, record)?;
        }
        if rows.table.len() == RESERVE_AFTER {
            rows.reserve(size, data_start as u64, records.consumed() as u64);
        }
    }
    if rows.table.is_empty() {
        return Err(SessionError::file(path, "no data rows after the header"));
    }
    Ok((rows.table, rows.extra))
}

/// The rows read before the table's room is reserved from the file size.
const RESERVE_AFTER: usize = 256;

/// The fields of a record as trimmed text, `None` when one is not UTF-8.
fn text_fields(record: Record<'_>) -> Option<Vec<String>> {
    record
        .fields()
        .map(|f| Some(std::str::from_utf8(f).ok()?.trim().to_string()))
        .collect()
}

/// A field of a record known to be UTF-8, trimmed.
fn text(field: &[u8]) -> &str {
    std::str::from_utf8(field).unwrap_or_default().trim()
}

fn not_utf8(path: &Path, line: u64) -> SessionError {
    SessionError::line(path, line, "the line is not valid UTF-8")
}

/// A table being read: its rows so far.
struct Rows<'a> {
    path: &'a Path,
    table: Table,
    extra: OptionalColumns,
    /// The field index of each optional column the header has.
    wanted: Vec<Option<usize>>,
    optional: &'a [&'a str],
}

impl Rows<'_> {
    /// Reserve room for the rows of a stream of `size` bytes whose rows so
    /// far took the bytes `start..now`.
    fn reserve(&mut self, size: u64, start: u64, now: u64) {
        let (rows, bytes) = (self.table.len() as u64, now.saturating_sub(start).max(1));
        // an eighth more than the rows so far suggest
        let more = (size.saturating_sub(now) * rows / bytes * 9 / 8) as usize;
        self.table.t.reserve(more);
        self.table.values.reserve(more * self.table.width());
        for values in self.extra.iter_mut().flatten() {
            values.reserve(more);
        }
    }

    /// Add the row of a record without quotes when every field it needs is
    /// a plain number ([`decimal`]), time does not go backwards and the
    /// record is ASCII; `false`, adding nothing, when not: [`Self::push`]
    /// then reads it.
    fn push_plain(&mut self, bytes: &[u8]) -> bool {
        let (rows, values) = (self.table.t.len(), self.table.values.len());
        let pushed = self.try_push_plain(bytes).is_some();
        if !pushed {
            self.table.t.truncate(rows);
            self.table.values.truncate(values);
            for values in self.extra.iter_mut().flatten() {
                values.truncate(rows);
            }
        }
        pushed
    }

    fn try_push_plain(&mut self, bytes: &[u8]) -> Option<()> {
        let (t, mut at) = decimal::field(bytes)?;
        let in_order = self.table.t.last().is_none_or(|&prev| t >= prev);
        if !(t.is_finite() && in_order) {
            return None;
        }
        self.table.t.push(t);
        for _ in 0..self.table.width() {
            if bytes.get(at) != Some(&b',') {
                return None;
            }
            let (v, n) = decimal::field(&bytes[at + 1..])?;
            if !v.is_finite() {
                return None;
            }
            self.table.values.push(v);
            at += 1 + n;
        }
        // the extra fields after the required ones, when there are any
        let rest = match bytes.get(at) {
            None => &[][..],
            Some(b',') if bytes[at..].is_ascii() => &bytes[at + 1..],
            Some(_) => return None,
        };
        let first_extra = self.table.width() + 1;
        for (k, values) in self.wanted.iter().zip(&mut self.extra) {
            let (Some(k), Some(values)) = (k, values) else {
                continue;
            };
            let field = Record::Plain(rest).fields().nth(k - first_extra)?;
            match decimal::field(field)? {
                (v, n) if n == field.len() && v.is_finite() => values.push(v),
                _ => return None,
            }
        }
        Some(())
    }

    /// Add the row of any record, or name its problem (the rules and
    /// messages of the module doc).
    fn push(&mut self, line: u64, record: Record<'_>) -> Result<(), SessionError> {
        let path = self.path;
        // a record is checked to be UTF-8 as a whole before its fields
        if record.fields().any(|f| std::str::from_utf8(f).is_err()) {
            return Err(not_utf8(path, line));
        }
        let (width, len) = (self.table.width(), record.len());
        if len < width + 1 {
            return Err(SessionError::line(
                path,
                line,
                format!("expected at least {} fields, found {len}", width + 1),
            ));
        }
        for (k, field) in record.fields().take(width + 1).map(text).enumerate() {
            let v: f64 = field.parse().map_err(|_| {
                let col = if k == 0 {
                    "t"
                } else {
                    &self.table.columns[k - 1]
                };
                SessionError::line(
                    path,
                    line,
                    format!("column `{col}`: `{field}` is not a number"),
                )
            })?;
            if !v.is_finite() {
                let col = if k == 0 {
                    "t"
                } else {
                    &self.table.columns[k - 1]
                };
                return Err(SessionError::line(
                    path,
                    line,
                    format!("column `{col}`: {field} is not a finite number"),
                ));
            }
            if k == 0 {
                if let Some(&prev) = self.table.t.last() {
                    if v < prev {
                        return Err(SessionError::line(
                            path,
                            line,
                            format!("time goes backwards: t = {v} after t = {prev}"),
                        ));
                    }
                }
                self.table.t.push(v);
            } else {
                self.table.values.push(v);
            }
        }
        for ((k, name), values) in self.wanted.iter().zip(self.optional).zip(&mut self.extra) {
            let (Some(k), Some(values)) = (k, values) else {
                continue;
            };
            let field = record.fields().nth(*k).map_or("", text);
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
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::{parse_table_with, reference};
    use super::*;

    /// A reader that hands out at most `chunk` bytes a call: records, numbers
    /// and line ends cut across the reads. (Never 3: csv-core takes a first
    /// read of just the 3 bytes of a byte-order mark for the end of the file
    /// — no file is read that way.)
    struct Chunked<'a>(&'a [u8], usize);

    impl std::io::Read for Chunked<'_> {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            let n = self.0.len().min(self.1).min(buf.len());
            buf[..n].copy_from_slice(&self.0[..n]);
            self.0 = &self.0[n..];
            Ok(n)
        }
    }

    /// The reader and the reference (the `csv` crate's records, trimmed and
    /// parsed by `str::parse`) agree on `text`: the same values bit for bit
    /// or the same error, whatever the size of the reads.
    fn agree(text: &[u8], columns: Columns<'_>, optional: &[&str], chunk: usize) {
        let path = Path::new("x.csv");
        let new = parse_table_with(Chunked(text, chunk), path, columns, optional);
        let old = reference::parse_table_with(Chunked(text, chunk), path, columns, optional);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let show = String::from_utf8_lossy(text);
        match (new, old) {
            (Ok((a, ea)), Ok((b, eb))) => {
                assert_eq!(a.columns, b.columns, "{show:?}");
                assert_eq!(bits(&a.t), bits(&b.t), "{show:?}");
                assert_eq!(bits(&a.values), bits(&b.values), "{show:?}");
                let extra = |e: &OptionalColumns| -> Vec<Option<Vec<u64>>> {
                    e.iter().map(|c| c.as_deref().map(bits)).collect()
                };
                assert_eq!(extra(&ea), extra(&eb), "{show:?}");
            }
            (Err(a), Err(b)) => assert_eq!(a.to_string(), b.to_string(), "{show:?}"),
            (a, b) => panic!("{show:?}: {a:?} but the reference gives {b:?}"),
        }
    }

    /// A random CSV text of a table: headers right and wrong, rows of numbers
    /// in every notation with blanks around them, now and then a bad field
    /// (not a number, NaN, quoted, not UTF-8), too few or extra fields, time
    /// going backwards, comments, blank lines, `\n`, `\r\n` and `\r`, a
    /// byte-order mark. About one row in `bad` has a problem (none for 0).
    fn table_text(lines: &[(u8, u64)], joints: bool, bad: u64) -> Vec<u8> {
        let mut rng = Rng(lines.len() as u64 + 1);
        let mut out = Vec::new();
        if rng.below(8) == 0 {
            out.extend_from_slice(b"\xef\xbb\xbf");
        }
        // the first `valid` headers are right
        let (headers, valid): (&[&[u8]], usize) = if joints {
            (
                &[
                    b"t,q1,q2",
                    b"t, q1 ,q2,x,extra",
                    b"t,q1,q2,q3",
                    b"t,q1,x,q2",
                    b"t,q2",
                    b"time,q1",
                    b" , ",
                ],
                2,
            )
        } else {
            (
                &[
                    b"t,ax,ay",
                    b"t,ax,ay,temp_c",
                    b"t , ax,ay,seq, temp_c ",
                    b"t,ax,ay,temp_c,temp_c",
                    b"\"t\",ax,\"ay\",temp_c",
                    b"t,ax",
                    b"t,ay,ax",
                    b"t,ax,ay,te\xffmp",
                    b"",
                ],
                5,
            )
        };
        let mut t = 0.0;
        let mut header_done = false;
        let fields = 3 + rng.below(3) as usize;
        for &(kind, seed) in lines {
            let mut r = Rng(seed);
            let odd = bad > 0 && r.below(bad) == 0;
            match kind {
                0..=4 => {
                    let lines: &[&[u8]] = &[b"# comment", b"#", b"", b"#,\"", b" ", b"  # not one"];
                    out.extend_from_slice(r.pick(&lines[..if odd { 6 } else { 4 }]));
                }
                _ if !header_done || (odd && kind < 8) => {
                    header_done = true;
                    let h = r.pick(&headers[..if odd { headers.len() } else { valid }]);
                    out.extend_from_slice(h);
                }
                _ => {
                    // a row
                    t += if odd && r.below(4) == 0 {
                        -0.5
                    } else {
                        1.0 / 120.0
                    };
                    let time = match r.below(4) {
                        _ if odd => number(&mut r, t, true),
                        0 => format!("{t:e}").into_bytes(),
                        _ => format!("{t:?}").into_bytes(),
                    };
                    let mut row = vec![time];
                    let n = match r.below(8) {
                        0 if odd => r.below(3) as usize,
                        1 => fields + r.below(3) as usize,
                        _ => fields,
                    };
                    for _ in 1..n {
                        let x = (r.next() as f64 / u64::MAX as f64 - 0.5) * 30.0;
                        row.push(number(&mut r, x, odd));
                    }
                    out.extend_from_slice(&row.join(&b","[..]));
                }
            }
            out.extend_from_slice(r.pick(&[
                &b"\n"[..],
                b"\n",
                b"\n",
                b"\n",
                b"\r\n",
                b"\r\n",
                b"\r",
                b"\n\n",
            ]));
        }
        if rng.below(4) == 0 {
            // no line end at the end
            while out.last().is_some_and(|b| b"\r\n".contains(b)) {
                out.pop();
            }
        }
        out
    }

    /// A field for the value `x`: in one of the notations robimu and other
    /// tools write, blanks around it; or (sometimes, when `odd`) something
    /// else.
    fn number(r: &mut Rng, x: f64, odd: bool) -> Vec<u8> {
        let text = match r.below(24) {
            0 | 1 if !odd => format!("{x:?}").into_bytes(),
            0 => r
                .pick(&[
                    "",
                    "abc",
                    "nan",
                    "NaN",
                    "inf",
                    "-inf",
                    "1e",
                    ".",
                    "-",
                    "+",
                    "1e400",
                    "1.5.2",
                    "\"1.5\"",
                    "\"2\n5\"",
                    "\"a\"\"b\"",
                    " \"1\"",
                    "1\"5",
                    "é",
                    "\u{a0}1.5",
                    "1.5\u{3000}",
                    "#1",
                    "0x10",
                    "1_0",
                    "+.5",
                    "5.",
                    "-.25e-3",
                    "1E+2",
                    "12345678901234567890123",
                    "0.000000000000000000000001234",
                ])
                .as_bytes()
                .to_vec(),
            1 => b"1.\xff5".to_vec(),
            2 => format!("{x:e}").into_bytes(),
            3 => format!("{x:.3}").into_bytes(),
            4 => format!("{}", x.round() as i64).into_bytes(),
            5 => format!("{:?}", x * 1e-7).into_bytes(),
            6 => format!("+{}", x.abs()).into_bytes(),
            _ => format!("{x:?}").into_bytes(),
        };
        let blank = |r: &mut Rng| -> &'static [u8] {
            r.pick(&[
                &b""[..],
                b"",
                b"",
                b"",
                b" ",
                b"\t",
                b"  ",
                b"\x0b",
                b"\x0c ",
            ])
        };
        [blank(r), &text[..], blank(r)].concat()
    }

    /// xorshift64: the texts are drawn from proptest's seeds.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            let mut x = self.0 | 1;
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            self.0 = x;
            x
        }
        fn below(&mut self, n: u64) -> u64 {
            self.next() % n
        }
        fn pick<T: Copy>(&mut self, from: &[T]) -> T {
            from[self.below(from.len() as u64) as usize]
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(3000))]

        /// The reader agrees with the reference on random tables, values and
        /// errors (file, line, cause), however the bytes arrive.
        #[test]
        fn agrees_with_the_reference(
            lines in proptest::collection::vec((0u8..40, proptest::prelude::any::<u64>()), 0..40),
            joints: bool,
            bad in proptest::prop_oneof![proptest::strategy::Just(0u64), 1u64..200],
            chunk in proptest::prop_oneof![1usize..3, 4usize..8, proptest::strategy::Just(1 << 20)],
        ) {
            let text = table_text(&lines, joints, bad);
            if joints {
                agree(&text, Columns::Joints, &[], chunk);
            } else {
                agree(&text, Columns::Fixed(&["ax", "ay"]), &["temp_c", "seq"], chunk);
            }
        }
    }

    /// The cases the random tables may miss: line numbers after comments,
    /// blank lines and `\r\n` (the `csv` crate's: the line after the previous
    /// record), quoted fields over several lines, a record longer than the
    /// buffer, byte-order marks.
    #[test]
    fn agrees_with_the_reference_on_edge_cases() {
        let fixed = Columns::Fixed(&["ax"]);
        let cases: &[&[u8]] = &[
            b"t,ax\n# c\n0,1\n\n\n1,x\n",
            b"t,ax\r\n0,1\r\n1,x\r\n",
            b"t,ax\r0,1\r1,x\r",
            b"t,ax\n0,1\r# c\r1,2\n2,x\n",
            b"# c\n\nt,ax,temp_c\n0,1\n",
            b"t,ax\n0,\"1\n2\"\n1,x\n",
            b"t,ax\n0,\"1\"\"\"\n",
            b"t,ax\n0,\"1\n",
            b"t,ax\n0,1,\"a,\nb\"\n1,x\n",
            b"\xef\xbb\xbft,ax\n0,1\n",
            b"\xef\xbb\xbf\xef\xbb\xbft,ax\n0,1\n",
            b"\xef\xbb\xbf\"t\",ax\n0,1\n",
            b"t,ax\n\xef\xbb\xbf0,1\n",
            b"t,ax\n0,1\n1,2,\xff\n",
            b"t,ax\n0,1\n1,2,\xc3\xa9\n",
            b"t,ax\n0,1\n1,\xc2\xa02\n",
            b"t,ax\n0,1\n  \n",
            b"t,ax\n0,1\n1,2",
            b"t,ax\n0,1\n1,2\n#",
            b"t,ax\n-0,-0\n0,+0\n",
            b"\n\n",
            b"#",
            b"\xff\n0,1\n",
            b"t,ax,temp_c\n0,1,2\n1,2\n",
            b"t,ax,temp_c\n0,1,\"2\"\n1,2, 3 \n",
        ];
        for text in cases {
            for chunk in [1, 2, 4, 5, 1 << 20] {
                agree(text, fixed, &["temp_c"], chunk);
            }
        }
        let mut long = b"t,ax\n0,1".to_vec();
        long.extend(std::iter::repeat_n(&b",2.5"[..], 50_000).flatten());
        long.extend_from_slice(b"\n1,x\n");
        agree(&long, fixed, &[], 1 << 20);
        agree(&long, fixed, &[], 7);
    }
}
