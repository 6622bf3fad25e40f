//! Numbers read straight from a table's bytes, with the value
//! `str::parse::<f64>` gives.
//!
//! The syntax is `f64::from_str`'s without `inf` and `nan`:
//! `[+-]? (d+ | d+ '.' d* | d* '.' d+) ([eE] [+-]? d+)?`, read by
//! `fast_float2` (Lemire's algorithm: correctly rounded, the standard
//! library's own method) without first making the field a `&str`.

/// A field's number and the bytes it takes: blanks (the whitespace a field is
/// trimmed of, short of the line ends `\n`, `\r` that cannot be in a field),
/// the number, blanks. `None` when the bytes do not start that way.
#[inline(always)]
pub(super) fn field(s: &[u8]) -> Option<(f64, usize)> {
    let start = blanks(s, 0);
    let (v, n) = number(&s[start..])?;
    Some((v, blanks(s, start + n)))
}

/// The index of the first byte from `i` on that is not a blank.
#[inline(always)]
fn blanks(s: &[u8], mut i: usize) -> usize {
    while let Some(b' ' | b'\t' | b'\x0b' | b'\x0c') = s.get(i) {
        i += 1;
    }
    i
}

/// The number at the start of `s` and its length; `inf`, `infinity` and
/// `nan` (which `fast_float2` reads) are not numbers here.
#[inline(always)]
fn number(s: &[u8]) -> Option<(f64, usize)> {
    let unsigned = match s.first() {
        Some(b'+' | b'-') => &s[1..],
        _ => s,
    };
    match unsigned.first() {
        Some(b'0'..=b'9' | b'.') => fast_float2::parse_partial(s).ok(),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn std(s: &str) -> Option<f64> {
        s.parse().ok()
    }

    /// `field` gives `from_str`'s value, bit for bit, or declines what
    /// `from_str` refuses.
    fn agrees(s: &str) {
        match (field(s.as_bytes()), std(s.trim())) {
            (Some((v, n)), Some(w)) if n == s.len() => {
                assert_eq!(v.to_bits(), w.to_bits(), "{s:?}: {v:e} against {w:e}")
            }
            (Some((_, n)), _) if n < s.len() => {} // stops before a byte that is not its own
            (Some((v, _)), None) => panic!("{s:?}: {v} but from_str refuses it"),
            (Some(_), Some(_)) => unreachable!(),
            (None, w) => {
                let word = s.to_ascii_lowercase();
                assert!(
                    w.is_none() || word.contains("inf") || word.contains("nan"),
                    "{s:?}: declined, from_str gives {w:?}"
                )
            }
        }
    }

    #[test]
    fn syntax_is_from_str() {
        for s in [
            "0",
            "-0",
            "+0",
            "1",
            "-1",
            "+1.5",
            "1.",
            ".5",
            "-.5",
            "+.5",
            ".",
            "-",
            "+",
            "",
            "e5",
            "1e5",
            "1E5",
            "1e+5",
            "1e-5",
            "1e",
            "1e+",
            "1.e3",
            ".1e-3",
            "0.0",
            "00012.500",
            "1_0",
            "0x10",
            "inf",
            "-inf",
            "NaN",
            "infinity",
            " 1.25 ",
            "\t-3\x0b",
            "1 2",
            "1,2",
            "--1",
            "+-1",
            "1.2.3",
            "1e5e5",
            "1e400",
            "-1e400",
            "1e-400",
            "4.9e-324",
            "2.2250738585072014e-308",
            "1.7976931348623157e308",
            "1.7976931348623159e308",
        ] {
            agrees(s);
        }
    }

    #[test]
    fn values_are_from_str() {
        for s in [
            "0.10305386920677025",
            "-0.20981360809429817",
            "0.008333333333333333",
            "6.903715933931634",
            "4.071405634154356e-5",
            "299.99166666666667",
            "9007199254740993",
            "9007199254740993e-5",
            "18446744073709551615",
            "18446744073709551616",
            "9999999999999999999",
            "9999999999999999999e-19",
            "1e-19",
            "1e-20",
            "12345678901234567890123",
            "0.000000000000000000000000000001",
            "1e22",
            "1e23",
            "123456789e19",
            "123456789e20",
            // halfway between two doubles, and just above and below
            "9007199254740993e-3",
            "9007199254740992.5e-3",
            "9007199254740993.0000000001e-3",
            "0.30000000000000004",
            "2.5e-10",
        ] {
            agrees(s);
            agrees(&format!("-{s}"));
        }
    }

    /// Exact ties `(2m + 1) · 5^k / 10^k = (2m + 1) / 2^k` between two
    /// doubles of the quotient path, and their neighbours.
    #[test]
    fn ties_round_to_even() {
        for k in 1..=3u32 {
            for j in 0..200u64 {
                let odd = (1u64 << 53) + 2 * j + 1;
                let w = odd * 5u64.pow(k) * (1 << (k - 1));
                for w in [w - 1, w, w + 1] {
                    agrees(&format!("{w}e-{k}"));
                    let digits = w.to_string();
                    let (int, frac) = digits.split_at(digits.len() - k as usize);
                    agrees(&format!("{int}.{frac}"));
                }
            }
        }
    }

    /// Random digit strings of every length and exponent against `from_str`,
    /// with the halfway cases that decide round-to-even.
    #[test]
    fn random_numbers_are_from_str() {
        let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        for _ in 0..200_000 {
            let r = next();
            let digits = 1 + (r % 21) as usize;
            let mut s: String = (0..digits)
                .map(|k| char::from(b'0' + ((next() >> (k % 8)) % 10) as u8))
                .collect();
            let point = (next() % (digits as u64 + 1)) as usize;
            s.insert(point, '.');
            match next() % 3 {
                0 => {}
                1 => s.push_str(&format!("e-{}", next() % 30)),
                _ => s.push_str(&format!("e{}", next() % 25)),
            }
            agrees(&s);
            // a double's decimal expansion ± a little: the hard roundings
            let f = f64::from_bits(next() >> 2);
            if f.is_finite() && f != 0.0 {
                agrees(&format!("{f:e}"));
                agrees(&format!("{f:.17e}"));
                agrees(&format!("{:.18e}", f * (1.0 + 1e-17)));
                let next_up = f64::from_bits(f.to_bits() + 1);
                agrees(&format!("{:.20e}", (f + next_up) / 2.0));
            }
        }
    }
}
