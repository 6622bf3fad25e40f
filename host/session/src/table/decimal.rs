//! Numbers read straight from a table's bytes, with the value
//! `str::parse::<f64>` gives.
//!
//! The syntax is `f64::from_str`'s without `inf` and `nan`:
//! `[+-]? (d+ | d+ '.' d* | d* '.' d+) ([eE] [+-]? d+)?`. A number of at most
//! 19 significant digits and a small decimal exponent — every number robimu
//! writes — is rounded here with exact integer arithmetic (round to nearest,
//! ties to even: the one correct result, so the standard library's); any
//! other is handed to the standard library.

/// A field's number and the bytes it takes: blanks (the whitespace a field is
/// trimmed of, short of the line ends `\n`, `\r` that cannot be in a field),
/// the number, blanks. `None` when the bytes do not start that way.
#[inline(always)]
pub(super) fn field(s: &[u8]) -> Option<(f64, usize)> {
    let start = blanks(s, 0);
    let (v, n) = number(s, start)?;
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

/// The number at `s[start..]` and its length.
#[inline(always)]
fn number(s: &[u8], start: usize) -> Option<(f64, usize)> {
    let (negative, mut i) = sign(s, start);
    let mut m = Mantissa::default();
    let int_start = i;
    // the integer part, usually short: one digit at a time
    while let Some(d) = digit(s, i) {
        m.push_digit(d);
        i += 1;
    }
    let mut digits = i - int_start;
    let mut exponent: i64 = 0;
    if s.get(i) == Some(&b'.') {
        i += 1;
        let frac_start = i;
        i = m.read(s, i);
        digits += i - frac_start;
        exponent = -((i - frac_start) as i64);
    }
    if digits == 0 {
        return None;
    }
    if let Some(b'e' | b'E') = s.get(i) {
        let (negative, from) = sign(s, i + 1);
        i = from;
        let mut e: i64 = 0;
        while let Some(d) = digit(s, i) {
            // saturated far beyond any exponent rounded here
            e = (e * 10 + i64::from(d)).min(1 << 32);
            i += 1;
        }
        if i == from {
            return None;
        }
        exponent += if negative { -e } else { e };
    }
    let exact = (m.count <= 19).then(|| value(m.digits, exponent)).flatten();
    let magnitude = match exact {
        Some(v) => v,
        // the text is ASCII; its syntax is `from_str`'s (module doc)
        None => {
            let v = std::str::from_utf8(&s[start..i]).ok()?.parse().ok()?;
            return Some((v, i - start));
        }
    };
    Some((if negative { -magnitude } else { magnitude }, i - start))
}

/// Whether `s[i]` is a minus sign, and the index after the sign if any.
#[inline(always)]
fn sign(s: &[u8], i: usize) -> (bool, usize) {
    match s.get(i) {
        Some(b'-') => (true, i + 1),
        Some(b'+') => (false, i + 1),
        _ => (false, i),
    }
}

/// The significant digits of a number as an integer.
#[derive(Default)]
struct Mantissa {
    /// The first 19 significant digits, while there are no more.
    digits: u64,
    /// How many significant digits there are (leading zeros are not): the
    /// number is in `digits` when at most 19.
    count: u32,
}

impl Mantissa {
    /// Add the digits from `s[i]` on; the index after them.
    #[inline(always)]
    fn read(&mut self, s: &[u8], mut i: usize) -> usize {
        while let Some(bytes) = s.get(i..).and_then(<[u8]>::first_chunk::<8>) {
            let (run, n) = digit_run(bytes);
            if n == 0 {
                return i;
            }
            self.push(run, n);
            i += n as usize;
            if n < 8 {
                return i;
            }
        }
        // fewer than 8 bytes left: one digit at a time
        while let Some(d) = digit(s, i) {
            self.push_digit(d);
            i += 1;
        }
        i
    }

    /// Add the digit `d`.
    #[inline(always)]
    fn push_digit(&mut self, d: u8) {
        if self.digits == 0 {
            // a leading zero is not significant
            self.digits = u64::from(d);
            self.count = u32::from(d != 0);
        } else {
            if self.count < 19 {
                self.digits = self.digits * 10 + u64::from(d);
            }
            self.count += 1;
        }
    }

    /// Add the `n` digits of a [`digit_run`] `run`.
    #[inline(always)]
    fn push(&mut self, run: u64, n: u32) {
        let v = run_value(run);
        if self.digits == 0 {
            // leading zeros are not significant: the run's significant
            // digits are those from its first non-zero byte on
            self.digits = v;
            self.count = 8 - run.trailing_zeros() / 8;
        } else {
            if self.count + n <= 19 {
                self.digits = self.digits * POW10_U64[n as usize] + v;
            }
            self.count += n;
        }
    }
}

/// The decimal digit at `s[i]`.
#[inline(always)]
fn digit(s: &[u8], i: usize) -> Option<u8> {
    let d = s.get(i)?.wrapping_sub(b'0');
    (d < 10).then_some(d)
}

/// The digits at the start of 8 bytes: how many there are (`n`), and their
/// values one a byte as the last `n` bytes of eight, the first in the
/// highest byte used (`digit_run_value` reads it), the bytes before 0.
#[inline(always)]
fn digit_run(bytes: &[u8; 8]) -> (u64, u32) {
    const ONES: u64 = 0x0101_0101_0101_0101;
    // byte k (the k-th character) minus '0': a digit's value where it is one
    // (a borrow out of a byte only spoils the bytes after it)
    let v = u64::from_le_bytes(*bytes).wrapping_sub(0x30 * ONES);
    // the high bit of each byte that is not 0..=9
    let not_digit = (v.wrapping_add(0x76 * ONES) | v) & (0x80 * ONES);
    let n = not_digit.trailing_zeros() / 8;
    // the n digits as the last of eight (zeros before them); none: 0
    (v.checked_shl(8 * (8 - n)).unwrap_or(0), n)
}

/// The number of the eight digits of a [`digit_run`].
#[inline(always)]
fn run_value(run: u64) -> u64 {
    // to pairs, then fours, then one number
    let pairs = (run * 10 + (run >> 8)) & 0x00ff_00ff_00ff_00ff;
    let fours = (pairs * 100 + (pairs >> 16)) & 0x0000_ffff_0000_ffff;
    (fours * 10_000 + (fours >> 32)) & 0xffff_ffff
}

/// `w · 10^q` correctly rounded, for the cases done exactly here; `None` for
/// the others.
#[inline(always)]
fn value(w: u64, q: i64) -> Option<f64> {
    if w == 0 {
        return Some(0.0);
    }
    if w <= 1 << 53 && (-22..=22).contains(&q) {
        // both exact in an f64: one correctly rounded operation (Clinger)
        let p = POW10_F64[q.unsigned_abs() as usize];
        return Some(if q < 0 { w as f64 / p } else { w as f64 * p });
    }
    match q {
        -19..=-1 => Some(quotient(w, POW10_U64[(-q) as usize])),
        // exact in a u128 (w < 2^64, 10^19 < 2^64), rounded once by `as`
        0..=19 => Some((u128::from(w) * u128::from(POW10_U64[q as usize])) as f64),
        _ => None,
    }
}

/// `w / d` correctly rounded, for `w ≥ 1`, `10 ≤ d ≤ 10^19`.
#[inline(always)]
fn quotient(w: u64, d: u64) -> f64 {
    // w · 2^s / d = quo + rem / d exactly: w · 2^s in [2^(63 + b), 2^(64 + b))
    // for d of b bits, so quo in (2^63, 2^65)
    let b = 64 - d.leading_zeros();
    let s = w.leading_zeros() + b;
    let n = u128::from(w) << s;
    let quo = n / u128::from(d);
    let rem = n - quo * u128::from(d);
    // quo's top 64 bits, and whether any bit below them is set
    let over = (quo >> 64) as u32;
    let top = (quo >> over) as u64;
    let sticky = rem != 0 || (over == 1 && quo & 1 == 1);
    // keep 53 bits: the 11 dropped bits and the sticky decide the rounding
    let mut mantissa = top >> 11;
    let low = top & 0x7ff;
    if low > 0x400 || (low == 0x400 && (sticky || mantissa & 1 == 1)) {
        mantissa += 1;
    }
    // value = mantissa · 2^(11 + over - s), normal (10^-19 to 2^64)
    let mut e2 = i64::from(11 + over) - i64::from(s);
    if mantissa == 1 << 53 {
        mantissa >>= 1;
        e2 += 1;
    }
    let biased = (e2 + 52 + 1023) as u64;
    f64::from_bits(biased << 52 | (mantissa & ((1 << 52) - 1)))
}

/// 10^0 … 10^22, all exact as f64.
const POW10_F64: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// 10^0 … 10^19.
const POW10_U64: [u64; 20] = {
    let mut p = [1u64; 20];
    let mut i = 1;
    while i < 20 {
        p[i] = p[i - 1] * 10;
        i += 1;
    }
    p
};

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
