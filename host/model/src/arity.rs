//! Arrays of fixed length in TOML and JSON inputs: a list of another length
//! is refused naming the length expected (serde reads `[f64; N]` from the
//! first N values of a TOML array and drops the rest).

use serde::de::Error;
use serde::{Deserialize, Deserializer};

/// An optional list of exactly `N` numbers (`#[serde(default,
/// deserialize_with = "robimu_model::arity::option")]`).
pub fn option<'de, D: Deserializer<'de>, const N: usize>(
    d: D,
) -> Result<Option<[f64; N]>, D::Error> {
    match Option::<Vec<f64>>::deserialize(d)? {
        None => Ok(None),
        Some(v) => exact(v).map(Some).map_err(D::Error::custom),
    }
}

/// A list of exactly `N` numbers (`#[serde(deserialize_with =
/// "robimu_model::arity::array")]`).
pub fn array<'de, D: Deserializer<'de>, const N: usize>(d: D) -> Result<[f64; N], D::Error> {
    exact(Vec::<f64>::deserialize(d)?).map_err(D::Error::custom)
}

/// `v` as `[f64; N]`, or the error naming both lengths (and the channels,
/// for the six of an IMU sample).
fn exact<const N: usize>(v: Vec<f64>) -> Result<[f64; N], String> {
    let n = v.len();
    v.try_into().map_err(|_| {
        let what = if N == 6 { " (ax ay az gx gy gz)" } else { "" };
        format!("{n} values where {N} are expected{what}")
    })
}

#[cfg(test)]
mod tests {
    #[derive(Debug, serde::Deserialize)]
    struct T {
        #[serde(default, deserialize_with = "super::option")]
        six: Option<[f64; 6]>,
    }

    #[test]
    fn only_the_exact_length_is_read() {
        let t: T = toml::from_str("six = [1, 2, 3, 4, 5, 6]").unwrap();
        assert_eq!(t.six, Some([1.0, 2.0, 3.0, 4.0, 5.0, 6.0]));
        assert_eq!(toml::from_str::<T>("").unwrap().six, None);
        for bad in ["six = [1, 2, 3, 4, 5, 6, 7]", "six = [1, 2, 3]"] {
            let e = toml::from_str::<T>(bad).unwrap_err().to_string();
            assert!(
                e.contains("values where 6 are expected (ax ay az gx gy gz)"),
                "{e}"
            );
        }
    }
}
