//! Mutations of a file's bytes: what a damaged disk, a cut transfer, an
//! editor or a hostile user does to a good file. Each [`mutate`] applies one
//! to three of them, chosen by a seeded RNG, and says which.

use rand::rngs::StdRng;
use rand::Rng;

/// Numbers that no physical field can have, or that wrap, overflow or
/// underflow when read.
const HOSTILE_NUMBERS: [&str; 16] = [
    "NaN",
    "nan",
    "inf",
    "-inf",
    "1e308",
    "-1e308",
    "1e309",
    "1e-320",
    "0",
    "-0",
    "-1",
    "4294967296",
    "18446744073709551615",
    "-9223372036854775808",
    "1e18",
    "",
];

/// Bytes that are not UTF-8 (a lone continuation byte, a bad lead, a
/// surrogate, an overlong encoding, a cut sequence).
const NOT_UTF8: [&[u8]; 5] = [
    b"\xff",
    b"\xc3\x28",
    b"\xed\xa0\x80",
    b"\xc0\xaf",
    b"\xe2\x82",
];

/// Openers that nest, for text formats (JSON/YAML/TOML arrays, XML
/// elements, YAML block sequences).
const NESTERS: [&str; 5] = ["[", "{", "<a>", "- ", "{\"a\":"];

/// 64-bit values for length and offset fields of binary formats.
const HOSTILE_U64: [u64; 6] = [
    0,
    u64::MAX,
    u64::MAX - 8,
    1 << 63,
    (1 << 32) - 1,
    0x7fff_ffff,
];

/// The largest input a mutation may make (the readers' own limits are far
/// below; this keeps one call short).
const MAX_LEN: usize = 4 << 20;

/// Applies one to three mutations to `bytes`; returns their names (for the
/// report of a finding).
pub fn mutate(rng: &mut StdRng, bytes: &mut Vec<u8>) -> Vec<&'static str> {
    let n = rng.random_range(1..=3);
    (0..n)
        .map(|_| {
            let name = mutate_once(rng, bytes);
            bytes.truncate(MAX_LEN);
            name
        })
        .collect()
}

fn mutate_once(rng: &mut StdRng, b: &mut Vec<u8>) -> &'static str {
    match rng.random_range(0..13) {
        0 => {
            for _ in 0..rng.random_range(1..=8) {
                if let Some(i) = pick(rng, b.len()) {
                    b[i] ^= 1 << rng.random_range(0..8);
                }
            }
            "bit flips"
        }
        1 => {
            for _ in 0..rng.random_range(1..=4) {
                if let Some(i) = pick(rng, b.len()) {
                    b[i] = rng.random();
                }
            }
            "byte overwrites"
        }
        2 => {
            let at = rng.random_range(0..=b.len());
            b.truncate(at);
            "truncation"
        }
        3 => {
            let at = rng.random_range(0..=b.len());
            let junk: Vec<u8> = (0..rng.random_range(1..=64))
                .map(|_| rng.random())
                .collect();
            b.splice(at..at, junk);
            "inserted garbage"
        }
        4 => {
            replace_number(rng, b);
            "hostile number"
        }
        5 => {
            duplicate_line(rng, b);
            "duplicated line"
        }
        6 => {
            swap_lines(rng, b);
            "reordered lines"
        }
        7 => {
            delete_line(rng, b);
            "deleted line"
        }
        8 => {
            let opener = NESTERS[rng.random_range(0..NESTERS.len())];
            let depth = [100, 1_000, 30_000, 100_000][rng.random_range(0..4)];
            let at = rng.random_range(0..=b.len());
            b.splice(at..at, opener.repeat(depth).into_bytes());
            "deep nesting"
        }
        9 => {
            let bad = NOT_UTF8[rng.random_range(0..NOT_UTF8.len())];
            let at = rng.random_range(0..=b.len());
            b.splice(at..at, bad.iter().copied());
            "invalid UTF-8"
        }
        10 => {
            change_field_count(rng, b);
            "wrong field count"
        }
        11 => {
            if b.len() >= 8 {
                let at = rng.random_range(0..=b.len() - 8) & !3;
                let v = HOSTILE_U64[rng.random_range(0..HOSTILE_U64.len())];
                b[at..at + 8].copy_from_slice(&v.to_le_bytes());
            }
            "hostile 64-bit field"
        }
        _ => {
            // a chunk of the file copied elsewhere in it
            if let (Some(from), Some(to)) = (pick(rng, b.len()), pick(rng, b.len())) {
                let len = rng.random_range(1..=256).min(b.len() - from);
                let chunk = b[from..from + len].to_vec();
                b.splice(to..to, chunk);
            }
            "spliced chunk"
        }
    }
}

fn pick(rng: &mut StdRng, len: usize) -> Option<usize> {
    (len > 0).then(|| rng.random_range(0..len))
}

/// The byte ranges of the lines of `b` (newline included).
fn lines(b: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut start = 0;
    for (i, &c) in b.iter().enumerate() {
        if c == b'\n' {
            out.push((start, i + 1));
            start = i + 1;
        }
    }
    if start < b.len() {
        out.push((start, b.len()));
    }
    out
}

fn duplicate_line(rng: &mut StdRng, b: &mut Vec<u8>) {
    let ls = lines(b);
    if let Some(k) = pick(rng, ls.len()) {
        let (s, e) = ls[k];
        let line = b[s..e].to_vec();
        let at = ls[rng.random_range(0..ls.len())].0;
        b.splice(at..at, line);
    }
}

fn swap_lines(rng: &mut StdRng, b: &mut Vec<u8>) {
    let ls = lines(b);
    if ls.len() < 2 {
        return;
    }
    let i = rng.random_range(0..ls.len() - 1);
    let j = rng.random_range(i + 1..ls.len());
    let (a, c) = (ls[i], ls[j]);
    let mut out = Vec::with_capacity(b.len());
    out.extend_from_slice(&b[..a.0]);
    out.extend_from_slice(&b[c.0..c.1]);
    out.extend_from_slice(&b[a.1..c.0]);
    out.extend_from_slice(&b[a.0..a.1]);
    out.extend_from_slice(&b[c.1..]);
    *b = out;
}

fn delete_line(rng: &mut StdRng, b: &mut Vec<u8>) {
    let ls = lines(b);
    if let Some(k) = pick(rng, ls.len()) {
        b.drain(ls[k].0..ls[k].1);
    }
}

/// Adds or removes a `,`-separated field on one line.
fn change_field_count(rng: &mut StdRng, b: &mut Vec<u8>) {
    let ls = lines(b);
    let Some(k) = pick(rng, ls.len()) else {
        return;
    };
    let (s, e) = ls[k];
    if rng.random_bool(0.5) {
        let at = if b[e - 1] == b'\n' { e - 1 } else { e };
        b.splice(at..at, b",0".iter().copied());
    } else if let Some(c) = b[s..e].iter().rposition(|&c| c == b',') {
        let end = b[s + c + 1..e]
            .iter()
            .position(|&c| c == b',' || c == b'\n')
            .map_or(e, |p| s + c + 1 + p);
        b.drain(s + c..end);
    }
}

/// Replaces one number of the text (a run of digits with its sign, point
/// and exponent) with one of [`HOSTILE_NUMBERS`].
fn replace_number(rng: &mut StdRng, b: &mut Vec<u8>) {
    let starts: Vec<usize> = (0..b.len())
        .filter(|&i| {
            let digit = |k: usize| b.get(k).is_some_and(u8::is_ascii_digit);
            let begins = digit(i) || (b[i] == b'-' && digit(i + 1));
            let after = i == 0 || !(b[i - 1].is_ascii_alphanumeric() || is_number_byte(b[i - 1]));
            begins && after
        })
        .collect();
    let Some(k) = pick(rng, starts.len()) else {
        return;
    };
    let s = starts[k];
    let e = (s + 1..b.len())
        .find(|&i| !is_number_byte(b[i]))
        .unwrap_or(b.len());
    let v = HOSTILE_NUMBERS[rng.random_range(0..HOSTILE_NUMBERS.len())];
    b.splice(s..e, v.bytes());
}

fn is_number_byte(c: u8) -> bool {
    c.is_ascii_digit() || matches!(c, b'.' | b'e' | b'E' | b'+' | b'-')
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn mutations_are_reproducible_from_the_seed_and_change_the_bytes() {
        let good = b"t,q1,q2\n0.0,1.5,2\n0.1,1.5,2\n".to_vec();
        let run = |seed| {
            let mut rng = StdRng::seed_from_u64(seed);
            (0..200)
                .map(|_| {
                    let mut b = good.clone();
                    let names = mutate(&mut rng, &mut b);
                    (b, names)
                })
                .collect::<Vec<_>>()
        };
        let (a, b) = (run(7), run(7));
        assert_eq!(a, b);
        let changed = a.iter().filter(|(m, _)| *m != good).count();
        assert!(changed > 180, "{changed} of 200 inputs changed");
        assert!(a.iter().all(|(m, _)| m.len() <= MAX_LEN));
    }

    #[test]
    fn a_number_is_replaced_whole() {
        let mut rng = StdRng::seed_from_u64(1);
        for _ in 0..50 {
            let mut b = b"x = -12.5e3\n".to_vec();
            replace_number(&mut rng, &mut b);
            let text = String::from_utf8(b).unwrap();
            assert!(
                HOSTILE_NUMBERS.iter().any(|v| text == format!("x = {v}\n")),
                "{text}"
            );
        }
    }
}
