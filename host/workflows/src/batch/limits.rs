//! The pass/fail limits of a production batch: a TOML file with one
//! `[limits]` table (docs/guide/calibrating.md "Production batches"). Parameter limits are
//! on result.json's values and σ (SI units, docs/model.md §5); the
//! residual limits on the whitened residual RMS (1 = as modelled).
//!
//! ```toml
//! [limits]
//! max_abs_bias_accel = 0.3        # m/s², every |b_a_*|
//! max_gain_error = 0.05           # every |k_* − 1|
//! max_residual_rms_accel = 1.5    # whitened
//! max_sigma."b_a_*" = 0.01        # σ of every parameter the glob names
//! max_deviation."r_a_*" = 0.09    # |value − prior mean|, rad
//! ```

use std::collections::BTreeMap;
use std::path::Path;

use robimu_session::result::CalibrationResult;
use serde::Deserialize;

/// The limits file's layout: one `[limits]` table.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct LimitsFile {
    limits: LimitsTable,
}

/// The `[limits]` table: every key optional.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct LimitsTable {
    max_abs_bias_accel: Option<f64>,
    max_abs_bias_gyro: Option<f64>,
    max_gain_error: Option<f64>,
    max_gain_error_accel: Option<f64>,
    max_gain_error_gyro: Option<f64>,
    max_misalignment: Option<f64>,
    max_residual_rms_accel: Option<f64>,
    max_residual_rms_gyro: Option<f64>,
    #[serde(default)]
    max_deviation: BTreeMap<String, f64>,
    #[serde(default)]
    max_sigma: BTreeMap<String, f64>,
}

/// What one limit bounds.
#[derive(Debug, Clone, PartialEq)]
enum Bound {
    /// |value − prior mean| of the parameters the glob names.
    Deviation(String),
    /// σ of the estimated parameters the glob names.
    Sigma(String),
    /// Whitened residual RMS of the accelerometer (0) or gyroscope (1).
    Rms(usize),
}

/// One limit: its key in the file, what it bounds and its maximum.
#[derive(Debug, Clone, PartialEq)]
struct Limit {
    key: String,
    bound: Bound,
    max: f64,
}

/// The limits of a batch (empty: every calibrated unit passes).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Limits {
    limits: Vec<Limit>,
}

/// A limits file that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum LimitsError {
    /// The file cannot be read.
    #[error("cannot read the limits file {path}: {source}")]
    Read {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// Not TOML, an unknown key, or a value that is no number.
    #[error("the limits file {path}: {message}")]
    Parse {
        /// The file.
        path: String,
        /// The parser's message (it names the key and line).
        message: String,
    },
    /// A maximum that is negative or not finite, or a bad glob.
    #[error("the limits file {path}: {key}: {message}")]
    Value {
        /// The file.
        path: String,
        /// The key.
        key: String,
        /// What is wrong.
        message: String,
    },
}

impl Limits {
    /// The limits of the TOML file at `path`.
    pub fn from_file(path: &Path) -> Result<Self, LimitsError> {
        let text =
            robimu_model::text::read_to_string(path).map_err(|source| LimitsError::Read {
                path: path.display().to_string(),
                source,
            })?;
        Self::from_toml(&text, &path.display().to_string())
    }

    /// The limits of a limits file's text (`path` names it in errors).
    pub fn from_toml(text: &str, path: &str) -> Result<Self, LimitsError> {
        let file: LimitsFile = toml::from_str(text).map_err(|e| LimitsError::Parse {
            path: path.to_string(),
            message: e.to_string().trim_end().to_string(),
        })?;
        let t = file.limits;
        let glob = |g: &str| Bound::Deviation(g.to_string());
        let mut limits = Vec::new();
        let named = [
            ("max_abs_bias_accel", t.max_abs_bias_accel, glob("b_a_*")),
            ("max_abs_bias_gyro", t.max_abs_bias_gyro, glob("b_w_*")),
            ("max_gain_error", t.max_gain_error, glob("k_*")),
            (
                "max_gain_error_accel",
                t.max_gain_error_accel,
                glob("k_a_*"),
            ),
            ("max_gain_error_gyro", t.max_gain_error_gyro, glob("k_w_*")),
            ("max_misalignment", t.max_misalignment, glob("gamma_*")),
            (
                "max_residual_rms_accel",
                t.max_residual_rms_accel,
                Bound::Rms(0),
            ),
            (
                "max_residual_rms_gyro",
                t.max_residual_rms_gyro,
                Bound::Rms(1),
            ),
        ];
        for (key, max, bound) in named {
            if let Some(max) = max {
                limits.push(Limit {
                    key: key.to_string(),
                    bound,
                    max,
                });
            }
        }
        for (table, map) in [
            ("max_deviation", &t.max_deviation),
            ("max_sigma", &t.max_sigma),
        ] {
            for (g, &max) in map {
                let key = format!("{table}.\"{g}\"");
                if g.is_empty()
                    || !g
                        .chars()
                        .all(|c| c.is_ascii_alphanumeric() || "_*?/".contains(c))
                {
                    return Err(LimitsError::Value {
                        path: path.to_string(),
                        key,
                        message: "a parameter name or glob (letters, digits, _, * and ?) expected"
                            .into(),
                    });
                }
                let bound = if table == "max_sigma" {
                    Bound::Sigma(g.clone())
                } else {
                    Bound::Deviation(g.clone())
                };
                limits.push(Limit { key, bound, max });
            }
        }
        if let Some(l) = limits.iter().find(|l| !(l.max.is_finite() && l.max >= 0.0)) {
            return Err(LimitsError::Value {
                path: path.to_string(),
                key: l.key.clone(),
                message: format!("the maximum must be a number >= 0 (got {})", l.max),
            });
        }
        Ok(Self { limits })
    }

    /// Whether there are no limits.
    pub fn is_empty(&self) -> bool {
        self.limits.is_empty()
    }

    /// The limits `result` fails, each as `KEY (NAME VALUE, … > MAX)`; a
    /// parameter limit whose glob names no parameter of `result` fails too.
    pub fn failures(&self, result: &CalibrationResult) -> Vec<String> {
        let mut out = Vec::new();
        for l in &self.limits {
            let over: Vec<String> = match &l.bound {
                Bound::Rms(sensor) => {
                    let Some(rms) = result.residual_rms else {
                        out.push(format!("{} (the result has no residual RMS)", l.key));
                        continue;
                    };
                    let v = sensor_rms(&rms)[*sensor];
                    if v > l.max || v.is_nan() {
                        vec![format!("rms {}", sig(v))]
                    } else {
                        Vec::new()
                    }
                }
                Bound::Deviation(g) | Bound::Sigma(g) => {
                    let sigma = matches!(l.bound, Bound::Sigma(_));
                    let named: Vec<_> = result
                        .parameters
                        .iter()
                        .filter(|p| glob_match(g, &p.name) && !(sigma && p.frozen))
                        .collect();
                    if named.is_empty() {
                        out.push(format!("{} (names no estimated parameter)", l.key));
                        continue;
                    }
                    named
                        .iter()
                        .filter_map(|p| {
                            let v = if sigma {
                                p.sigma
                            } else {
                                (p.value - p.prior).abs()
                            };
                            // NaN fails
                            (v > l.max || v.is_nan()).then(|| {
                                if sigma {
                                    format!("{} σ {}", p.name, sig(v))
                                } else {
                                    format!("{} {}", p.name, sig(v))
                                }
                            })
                        })
                        .collect()
                }
            };
            if !over.is_empty() {
                out.push(format!("{} ({} > {})", l.key, over.join(", "), l.max));
            }
        }
        out
    }
}

/// The whitened residual RMS of the accelerometer and the gyroscope from
/// the six channels' `[ax, ay, az, gx, gy, gz]`: √(mean of the squares).
pub(crate) fn sensor_rms(rms: &[f64; 6]) -> [f64; 2] {
    let m = |c: &[f64]| (c.iter().map(|v| v * v).sum::<f64>() / 3.0).sqrt();
    [m(&rms[..3]), m(&rms[3..])]
}

/// `v` with 4 significant digits.
fn sig(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return v.to_string();
    }
    let decimals = (3 - v.abs().log10().floor() as i32).clamp(0, 15) as usize;
    format!("{v:.decimals$}")
}

/// Whether `name` matches the glob `pattern` (`*`: any run of characters,
/// `?`: one character, everything else literally).
pub(crate) fn glob_match(pattern: &str, name: &str) -> bool {
    let (p, n): (Vec<char>, Vec<char>) = (pattern.chars().collect(), name.chars().collect());
    // the classic two-pointer match with backtracking to the last `*`
    let (mut i, mut j, mut star, mut mark) = (0, 0, None, 0);
    while j < n.len() {
        if i < p.len() && (p[i] == '?' || p[i] == n[j]) {
            i += 1;
            j += 1;
        } else if i < p.len() && p[i] == '*' {
            star = Some(i);
            mark = j;
            i += 1;
        } else if let Some(s) = star {
            i = s + 1;
            mark += 1;
            j = mark;
        } else {
            return false;
        }
    }
    p[i..].iter().all(|&c| c == '*')
}

#[cfg(test)]
mod tests {
    use super::*;
    use robimu_session::result::ParameterResult;

    fn param(name: &str, value: f64, prior: f64, sigma: f64) -> ParameterResult {
        ParameterResult {
            name: name.into(),
            unit: "1".into(),
            value,
            prior,
            prior_sigma: 1.0,
            sigma,
            frozen: false,
        }
    }

    fn result(params: Vec<ParameterResult>, rms: [f64; 6]) -> CalibrationResult {
        let mut r: CalibrationResult = serde_json::from_value(serde_json::json!({
            "format": robimu_session::result::RESULT_FORMAT,
            "parameters": [],
            "covariance": {"names": [], "matrix": []},
        }))
        .unwrap();
        r.parameters = params;
        r.residual_rms = Some(rms);
        r
    }

    #[test]
    fn globs_match_like_a_shell() {
        for (p, n, want) in [
            ("b_a_*", "b_a_x", true),
            ("b_a_*", "b_w_x", false),
            ("k_*", "k_w_z", true),
            ("*_x", "b_a_x", true),
            ("*_x", "b_a_y", false),
            ("b_?_x", "b_w_x", true),
            ("b_?_x", "b_ww_x", false),
            ("tau", "tau", true),
            ("tau", "tau2", false),
            ("*a*a*", "gamma_a_yz", true),
            ("*", "", true),
            ("", "x", false),
        ] {
            assert_eq!(glob_match(p, n), want, "{p} vs {n}");
        }
    }

    #[test]
    fn each_limit_fails_exactly_the_parameters_beyond_it() {
        let limits = Limits::from_toml(
            "[limits]\nmax_abs_bias_accel = 0.3\nmax_gain_error = 0.05\n\
             max_sigma.\"b_*\" = 0.01\nmax_residual_rms_gyro = 1.5\nmax_deviation.tau = 0.2\n",
            "l.toml",
        )
        .unwrap();
        let params = vec![
            param("b_a_x", -0.31, 0.0, 0.001),
            param("b_a_y", 0.29, 0.0, 0.02),
            param("b_w_x", 5.0, 0.0, 0.001), // no gyro bias limit
            param("k_a_x", 1.04, 1.0, 0.001),
            param("k_w_y", 0.94, 1.0, 0.001),
            param("tau", -0.1, 0.0, 0.001),
        ];
        // gyro rms √((1.2² + 1.8² + 1.5²)/3) = √2.31 = 1.51987
        let f = limits.failures(&result(params.clone(), [1.0, 1.0, 1.0, 1.2, 1.8, 1.5]));
        assert_eq!(
            f,
            [
                "max_abs_bias_accel (b_a_x 0.3100 > 0.3)",
                "max_gain_error (k_w_y 0.06000 > 0.05)",
                "max_residual_rms_gyro (rms 1.520 > 1.5)",
                "max_sigma.\"b_*\" (b_a_y σ 0.02000 > 0.01)",
            ]
        );
        // within every limit
        let mut ok = params;
        ok[0].value = 0.2;
        ok[1].sigma = 0.005;
        ok[4].value = 0.96;
        assert!(limits
            .failures(&result(ok.clone(), [1.0, 1.0, 1.0, 1.2, 1.6, 1.5]))
            .is_empty());
        // a glob that names nothing fails
        let l = Limits::from_toml("[limits]\nmax_sigma.\"q_*\" = 1\n", "l.toml").unwrap();
        assert_eq!(
            l.failures(&result(ok, [1.0; 6])),
            ["max_sigma.\"q_*\" (names no estimated parameter)"]
        );
    }

    #[test]
    fn bad_files_name_the_key() {
        let err = |t: &str| Limits::from_toml(t, "l.toml").unwrap_err().to_string();
        let e = err("[limits]\nmax_bais_accel = 0.3\n");
        assert!(e.contains("unknown field `max_bais_accel`"), "{e}");
        let e = err("[limit]\nmax_gain_error = 0.3\n");
        assert!(e.contains("unknown field `limit`"), "{e}");
        let e = err("[limits]\nmax_gain_error = -1\n");
        assert!(e.contains("max_gain_error: the maximum must be"), "{e}");
        let e = err("[limits]\nmax_sigma.\"b a\" = 1\n");
        assert!(e.contains("max_sigma.\"b a\""), "{e}");
        let e = err("[limits]\nmax_gain_error = \"x\"\n");
        assert!(e.contains("max_gain_error"), "{e}");
        assert!(Limits::from_toml("[limits]\n", "l.toml")
            .unwrap()
            .is_empty());
    }
}
