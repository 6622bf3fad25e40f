//! `truth.toml`: the true value of every parameter of x, for simulated
//! sessions (docs/model.md §7): one `name = value` line each, §5 names, SI units.

use std::path::Path;

use robimu_model::ParamLayout;

use super::error::toml_error;
use super::SessionError;

/// A truth that does not list exactly the parameters of a layout.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TruthMismatch {
    /// A value for a parameter the layout does not have.
    #[error("`{0}` is not a parameter of this robot (see docs/model.md §5 for the names)")]
    Unknown(String),
    /// No value for a parameter of the layout.
    #[error("`{0}` is missing")]
    Missing(String),
}

/// Parameter name → true value, in file order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Truth {
    /// `(name, value)` pairs in file order.
    pub values: Vec<(String, f64)>,
}

impl Truth {
    /// The truth `x` of every parameter of `layout`.
    pub fn of(layout: &ParamLayout, x: &[f64]) -> Self {
        Self {
            values: layout
                .specs()
                .iter()
                .zip(x)
                .map(|(s, v)| (s.name.clone(), *v))
                .collect(),
        }
    }

    /// IMU `j`'s view of a multi-IMU truth (docs/model.md §9) under the
    /// one-IMU names: the shared and IMU 0's entries, IMU j's `imu<j>/X` in
    /// the place of `X`; the other IMUs' left out.
    pub fn of_imu(&self, j: usize) -> Truth {
        let prefix = format!("imu{j}/");
        let own: Vec<(&str, f64)> = self
            .values
            .iter()
            .filter_map(|(n, v)| n.strip_prefix(&prefix).map(|b| (b, *v)))
            .collect();
        let values = self
            .values
            .iter()
            .filter(|(n, _)| crate::result::split_imu_name(n).is_none())
            .map(|(n, v)| {
                let v = own.iter().find(|(b, _)| b == n).map_or(*v, |(_, w)| *w);
                (n.clone(), v)
            })
            .collect();
        Truth { values }
    }

    /// x in `layout` order: every parameter of `layout`, and nothing else.
    pub fn vector(&self, layout: &ParamLayout) -> Result<Vec<f64>, TruthMismatch> {
        if let Some((name, _)) = self
            .values
            .iter()
            .find(|(n, _)| layout.index_of(n).is_none())
        {
            return Err(TruthMismatch::Unknown(name.clone()));
        }
        layout
            .specs()
            .iter()
            .map(|s| {
                self.get(&s.name)
                    .ok_or_else(|| TruthMismatch::Missing(s.name.clone()))
            })
            .collect()
    }

    /// The true value of `name`, if listed.
    pub fn get(&self, name: &str) -> Option<f64> {
        self.values.iter().find(|(n, _)| n == name).map(|(_, v)| *v)
    }

    /// Read `path`.
    pub fn read(path: &Path) -> Result<Self, SessionError> {
        let text = crate::text::read(path)?;
        Self::parse(&text, path)
    }

    /// Parse; `path` only names the file in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Self, SessionError> {
        let table: toml::Table = toml::from_str(text).map_err(|e| toml_error(path, text, &e))?;
        // `preserve_order` keeps the table in file order.
        let mut values = Vec::with_capacity(table.len());
        for (name, value) in &table {
            let v = match value {
                toml::Value::Float(f) => *f,
                toml::Value::Integer(i) => *i as f64,
                other => {
                    return Err(SessionError::file(
                        path,
                        format!("`{name}` must be a number, found {}", other.type_str()),
                    ))
                }
            };
            if !v.is_finite() {
                return Err(SessionError::file(
                    path,
                    format!("`{name}` = {v} is not finite"),
                ));
            }
            values.push((name.clone(), v));
        }
        Ok(Self { values })
    }

    /// The TOML text: one `name = value` line each, values with full precision.
    pub fn to_toml(&self) -> String {
        let mut s = String::from("# true parameter values (SI units), docs/model.md §5 names\n");
        for (n, v) in &self.values {
            // bare keys as before; IMU j's names (`imu1/k_a_x`, §9) quoted
            if n.bytes()
                .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-')
            {
                s.push_str(&format!("{n} = {v:?}\n"));
            } else {
                s.push_str(&format!("{n:?} = {v:?}\n"));
            }
        }
        s
    }
}

/// One parameter of a truth check: an estimate with its σ against the
/// truth of a simulated session.
#[derive(Clone, Debug)]
pub struct TruthRow {
    /// Parameter name.
    pub name: String,
    /// Estimate, SI.
    pub estimate: f64,
    /// Its posterior σ.
    pub sigma: f64,
    /// The twin's truth (docs/model.md §4.8).
    pub truth: f64,
    /// The part of `truth` that is the model's share of the twin's
    /// structural mode (what it absorbs of an effect it does not have,
    /// docs/model.md §4.8); 0 without a mode.
    pub mode_share: f64,
}

impl TruthRow {
    /// (estimate − truth)/σ.
    pub fn z(&self) -> f64 {
        (self.estimate - self.truth) / self.sigma
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_truth_lists_exactly_the_layouts_parameters() {
        let layout = ParamLayout::new(&robimu_model::Robot::aubo_i5());
        let x: Vec<f64> = (0..layout.len()).map(|k| k as f64 * 0.5).collect();
        let t = Truth::of(&layout, &x);
        assert_eq!(t.vector(&layout).unwrap(), x);
        let mut extra = t.clone();
        extra.values.push(("eps_9_9".into(), 0.0));
        assert_eq!(
            extra.vector(&layout),
            Err(TruthMismatch::Unknown("eps_9_9".into()))
        );
        let mut short = t;
        short.values.retain(|(n, _)| n != "tau");
        let err = short.vector(&layout).unwrap_err();
        assert_eq!(err.to_string(), "`tau` is missing");
    }

    #[test]
    fn round_trip_exact_and_ordered() {
        let t = Truth {
            values: vec![
                ("tau".into(), -2.718_281_828_459_1),
                ("eps_1_1".into(), 1e-4),
                ("k_a_x".into(), 1.0),
            ],
        };
        let back = Truth::parse(&t.to_toml(), Path::new("truth.toml")).unwrap();
        assert_eq!(back, t);
        assert_eq!(back.get("tau"), Some(-2.718_281_828_459_1));
    }

    #[test]
    fn rejects_non_numbers() {
        let e = Truth::parse("tau = \"x\"\n", Path::new("truth.toml")).unwrap_err();
        assert!(e.to_string().contains("`tau` must be a number"), "{e}");
    }
}
