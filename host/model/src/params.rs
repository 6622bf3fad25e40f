//! The parameter vector x (paper Table I; docs/model.md §5): names, units, prior
//! means and σ, and typed views.
//!
//! Order: ε (estimated set, by link then k), g_x, g_y, τ, γ_a, r_a, k_a, b_a,
//! γ_ω, r_ω, k_ω, b_ω. For the AUBO i5 (21 ε) x has 48 entries. ε not in the
//! estimated set are fixed at their nominal value: 0, except ε_n1..3 (the IMU
//! position), fixed at the mount position; ε_n4..6 are always 0.

use super::imu::ImuIntrinsics;
use super::jet::Scalar;
use super::robot::{ErrorIndex, Robot};

/// One entry of x.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamSpec {
    /// Name from docs/model.md §5 (`eps_2_4`, `g_x`, `tau`, `gamma_a_yz`, …).
    pub name: String,
    /// Unit string in files: `m`, `rad`, `m/s^2`, `s`, `1`, `rad/s`.
    pub unit: &'static str,
    /// Prior mean x̂.
    pub nominal: f64,
    /// Prior standard deviation.
    pub sigma: f64,
}

/// Start index of each block of x.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Offsets {
    /// ε block (always 0).
    pub eps: usize,
    /// g_x, g_y.
    pub g_xy: usize,
    /// τ.
    pub tau: usize,
    /// γ_a (yz, zy, zx).
    pub gamma_a: usize,
    /// r_a (z, y, x).
    pub r_a: usize,
    /// k_a (x, y, z).
    pub k_a: usize,
    /// b_a (x, y, z).
    pub b_a: usize,
    /// γ_ω.
    pub gamma_w: usize,
    /// r_ω.
    pub r_w: usize,
    /// k_ω.
    pub k_w: usize,
    /// b_ω.
    pub b_w: usize,
    /// Total length of x.
    pub len: usize,
}

impl Offsets {
    fn new(n_eps: usize) -> Self {
        let g_xy = n_eps;
        Self {
            eps: 0,
            g_xy,
            tau: g_xy + 2,
            gamma_a: g_xy + 3,
            r_a: g_xy + 6,
            k_a: g_xy + 9,
            b_a: g_xy + 12,
            gamma_w: g_xy + 15,
            r_w: g_xy + 18,
            k_w: g_xy + 21,
            b_w: g_xy + 24,
            len: g_xy + 27,
        }
    }
}

/// x has the wrong length.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("parameter vector has {found} entries; this layout needs {expected}")]
pub struct ParamLengthError {
    /// Layout length.
    pub expected: usize,
    /// Given length.
    pub found: usize,
}

/// The groups [`ParamLayout::select`] understands besides parameter names:
/// `lengths`, the robot length errors ([`ParamLayout::lengths`]).
pub const PARAM_GROUPS: &[&str] = &["lengths"];

/// An item of a parameter selection that is neither a group nor a parameter.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown parameter `{name}`; valid: {valid}")]
pub struct UnknownParameter {
    /// The item.
    pub name: String,
    /// The groups and parameter names, comma-separated.
    pub valid: String,
}

/// Typed view of x: the full ε table (estimated and fixed), gravity, τ and
/// both sensors' intrinsics.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelParams<S = f64> {
    /// ε_i1..6 of links 1..=n (`eps[i-1][k-1]`).
    pub eps: Vec<[S; 6]>,
    /// (g_x, g_y) (m/s²).
    pub g_xy: [S; 2],
    /// τ (s).
    pub tau: S,
    /// Accelerometer intrinsics.
    pub accel: ImuIntrinsics<S>,
    /// Gyroscope intrinsics.
    pub gyro: ImuIntrinsics<S>,
}

/// The layout of x for one robot.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamLayout {
    specs: Vec<ParamSpec>,
    estimated: Vec<ErrorIndex>,
    fixed_eps: Vec<[f64; 6]>,
    offsets: Offsets,
}

const XYZ: [&str; 3] = ["x", "y", "z"];
const ZYX: [&str; 3] = ["z", "y", "x"];
const GAMMA: [&str; 3] = ["yz", "zy", "zx"];

impl ParamLayout {
    /// The layout for `robot`: its estimated ε set and its priors.
    pub fn new(robot: &Robot) -> Self {
        let n = robot.dof();
        let mount = robot.mount();
        let pr = robot.priors();
        let mut fixed_eps = vec![[0.0; 6]; n];
        fixed_eps[n - 1][..3].copy_from_slice(&mount.position);
        let estimated = robot.estimated_errors().to_vec();
        let mut specs = Vec::with_capacity(estimated.len() + 27);
        for e in &estimated {
            let imu_pos = e.link == n && e.is_translation();
            let (unit, sigma) = match (imu_pos, e.is_translation()) {
                (true, _) => ("m", mount.position_sigma),
                (false, true) => ("m", pr.eps_length_sigma),
                (false, false) => ("rad", pr.eps_angle_sigma),
            };
            specs.push(ParamSpec {
                name: format!("eps_{}_{}", e.link, e.k),
                unit,
                nominal: fixed_eps[e.link - 1][e.k - 1],
                sigma,
            });
        }
        let mut push = |name: String, unit, nominal, sigma| {
            specs.push(ParamSpec {
                name,
                unit,
                nominal,
                sigma,
            })
        };
        push("g_x".into(), "m/s^2", 0.0, pr.g_xy_sigma);
        push("g_y".into(), "m/s^2", 0.0, pr.g_xy_sigma);
        push("tau".into(), "s", 0.0, pr.tau_sigma);
        for (s, r_nom, gamma_sigma, k_sigma, b_sigma, b_unit) in [
            (
                "a",
                mount.r_a,
                pr.gamma_a_sigma,
                pr.k_a_sigma,
                pr.b_a_sigma,
                "m/s^2",
            ),
            (
                "w",
                mount.r_w,
                pr.gamma_w_sigma,
                pr.k_w_sigma,
                pr.b_w_sigma,
                "rad/s",
            ),
        ] {
            for g in GAMMA {
                push(format!("gamma_{s}_{g}"), "rad", 0.0, gamma_sigma);
            }
            for (i, ax) in ZYX.iter().enumerate() {
                push(format!("r_{s}_{ax}"), "rad", r_nom[i], mount.rotation_sigma);
            }
            for ax in XYZ {
                push(format!("k_{s}_{ax}"), "1", 1.0, k_sigma);
            }
            for ax in XYZ {
                push(format!("b_{s}_{ax}"), b_unit, 0.0, b_sigma);
            }
        }
        let offsets = Offsets::new(estimated.len());
        debug_assert_eq!(specs.len(), offsets.len);
        Self {
            specs,
            estimated,
            fixed_eps,
            offsets,
        }
    }

    /// Number of parameters.
    pub fn len(&self) -> usize {
        self.specs.len()
    }
    /// Never true (x always holds the 27 non-ε parameters).
    pub fn is_empty(&self) -> bool {
        self.specs.is_empty()
    }
    /// Every parameter in x order.
    pub fn specs(&self) -> &[ParamSpec] {
        &self.specs
    }
    /// Block offsets.
    pub fn offsets(&self) -> Offsets {
        self.offsets
    }
    /// Estimated ε in x order (`x[i]` is ε `estimated_errors()[i]` for i < count).
    pub fn estimated_errors(&self) -> &[ErrorIndex] {
        &self.estimated
    }
    /// Number of links n.
    pub fn n_links(&self) -> usize {
        self.fixed_eps.len()
    }
    /// Values of ε when not estimated (`[link-1][k-1]`).
    pub fn fixed_eps(&self) -> &[[f64; 6]] {
        &self.fixed_eps
    }
    /// Index of the parameter named `name` (docs/model.md §5).
    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.specs.iter().position(|s| s.name == name)
    }
    /// Index of ε_{link,k} if it is estimated.
    pub fn eps_index(&self, link: usize, k: usize) -> Option<usize> {
        self.estimated
            .iter()
            .position(|e| e.link == link && e.k == k)
    }
    /// Indices in x of the robot length errors ε_i1..3 of links i < n (not
    /// the IMU position ε_n1..3), in x order.
    pub fn lengths(&self) -> Vec<usize> {
        let n = self.n_links();
        (0..self.estimated.len())
            .filter(|&i| self.estimated[i].is_length(n))
            .collect()
    }

    /// Indices in x, sorted and without repeats, of the parameters `items`
    /// name: groups ([`PARAM_GROUPS`]: `lengths`) and parameter names
    /// (docs/model.md §5); blank items are skipped.
    pub fn select<S: AsRef<str>>(&self, items: &[S]) -> Result<Vec<usize>, UnknownParameter> {
        let mut out = Vec::new();
        for item in items
            .iter()
            .map(|s| s.as_ref().trim())
            .filter(|s| !s.is_empty())
        {
            if let Some(group) = self.group(item) {
                out.extend(group);
            } else if let Some(k) = self.index_of(item) {
                out.push(k);
            } else {
                let names: Vec<&str> = PARAM_GROUPS
                    .iter()
                    .copied()
                    .chain(self.specs.iter().map(|s| s.name.as_str()))
                    .collect();
                return Err(UnknownParameter {
                    name: item.to_string(),
                    valid: names.join(", "),
                });
            }
        }
        out.sort_unstable();
        out.dedup();
        Ok(out)
    }

    /// The members of the group named `name` ([`PARAM_GROUPS`]).
    fn group(&self, name: &str) -> Option<Vec<usize>> {
        match name {
            "lengths" => Some(self.lengths()),
            _ => None,
        }
    }

    /// Prior means x̂.
    pub fn nominal(&self) -> Vec<f64> {
        self.specs.iter().map(|s| s.nominal).collect()
    }
    /// Prior σ.
    pub fn sigmas(&self) -> Vec<f64> {
        self.specs.iter().map(|s| s.sigma).collect()
    }

    /// Typed view of `x`.
    pub fn unpack<S: Scalar>(&self, x: &[S]) -> Result<ModelParams<S>, ParamLengthError> {
        if x.len() != self.len() {
            return Err(ParamLengthError {
                expected: self.len(),
                found: x.len(),
            });
        }
        let mut eps: Vec<[S; 6]> = self.fixed_eps.iter().map(|row| row.map(S::cst)).collect();
        for (i, e) in self.estimated.iter().enumerate() {
            eps[e.link - 1][e.k - 1] = x[i];
        }
        let o = &self.offsets;
        let v3 = |at: usize| [x[at], x[at + 1], x[at + 2]];
        Ok(ModelParams {
            eps,
            g_xy: [x[o.g_xy], x[o.g_xy + 1]],
            tau: x[o.tau],
            accel: ImuIntrinsics {
                gamma: v3(o.gamma_a),
                r: v3(o.r_a),
                k: v3(o.k_a),
                b: v3(o.b_a),
            },
            gyro: ImuIntrinsics {
                gamma: v3(o.gamma_w),
                r: v3(o.r_w),
                k: v3(o.k_w),
                b: v3(o.b_w),
            },
        })
    }

    /// x from a typed view (ε outside the estimated set are dropped).
    pub fn pack(&self, p: &ModelParams) -> Vec<f64> {
        let mut x = Vec::with_capacity(self.len());
        for e in &self.estimated {
            x.push(p.eps[e.link - 1][e.k - 1]);
        }
        x.extend_from_slice(&p.g_xy);
        x.push(p.tau);
        for s in [&p.accel, &p.gyro] {
            x.extend_from_slice(&s.gamma);
            x.extend_from_slice(&s.r);
            x.extend_from_slice(&s.k);
            x.extend_from_slice(&s.b);
        }
        x
    }
}

/// Draw a ground truth x from the priors of `layout` (Gaussian, seeded):
/// x_k = x̂_k + σ_k·n_k with n_k standard normal (docs/model.md §5).
pub fn draw_truth<R: rand::Rng>(layout: &ParamLayout, rng: &mut R) -> Vec<f64> {
    use rand_distr::{Distribution, StandardNormal};
    layout
        .specs()
        .iter()
        .map(|s| {
            let z: f64 = StandardNormal.sample(rng);
            s.nominal + s.sigma * z
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn select_understands_groups_and_names() {
        let l = ParamLayout::new(&Robot::aubo_i5());
        let lengths = l.lengths();
        let names: Vec<&str> = lengths
            .iter()
            .map(|&k| l.specs()[k].name.as_str())
            .collect();
        // the nine robot lengths of the paper; the IMU position eps_6_1..3 is not one
        assert_eq!(
            names,
            "eps_1_1 eps_2_1 eps_2_2 eps_3_1 eps_3_2 eps_4_1 eps_4_2 eps_5_1 eps_5_2"
                .split_whitespace()
                .collect::<Vec<_>>()
        );
        let tau = l.offsets().tau;
        let got = l.select(&[" tau", "lengths", "", "eps_2_1"]).unwrap();
        let mut want = lengths.clone();
        want.push(tau);
        assert_eq!(got, want);
        assert_eq!(l.select::<&str>(&[]).unwrap(), Vec::<usize>::new());
        let err = l.select(&["lengths", "tua"]).unwrap_err();
        assert_eq!(err.name, "tua");
        assert!(err.valid.starts_with("lengths, eps_1_1, eps_1_6,"), "{err}");
        assert!(err
            .to_string()
            .starts_with("unknown parameter `tua`; valid: lengths, eps_1_1"));
    }

    #[test]
    fn aubo_layout_has_the_model_md_names_order_and_priors() {
        let l = ParamLayout::new(&Robot::aubo_i5());
        assert_eq!(l.len(), 48);
        let names: Vec<&str> = l.specs().iter().map(|s| s.name.as_str()).collect();
        let expected = "eps_1_1 eps_1_6 eps_2_1 eps_2_2 eps_2_4 eps_2_6 eps_3_1 eps_3_2 eps_3_4 \
            eps_3_6 eps_4_1 eps_4_2 eps_4_4 eps_4_6 eps_5_1 eps_5_2 eps_5_4 eps_5_6 eps_6_1 \
            eps_6_2 eps_6_3 g_x g_y tau gamma_a_yz gamma_a_zy gamma_a_zx r_a_z r_a_y r_a_x \
            k_a_x k_a_y k_a_z b_a_x b_a_y b_a_z gamma_w_yz gamma_w_zy gamma_w_zx r_w_z r_w_y \
            r_w_x k_w_x k_w_y k_w_z b_w_x b_w_y b_w_z";
        assert_eq!(names, expected.split_whitespace().collect::<Vec<_>>());
        let get = |n: &str| &l.specs()[l.index_of(n).unwrap()];
        let deg = 1f64.to_radians();
        let cases: [(&str, &str, f64, f64); 14] = [
            ("eps_2_2", "m", 0.0, 1e-3),
            ("eps_3_4", "rad", 0.0, deg),
            ("eps_6_1", "m", 0.0252, 0.01),
            ("eps_6_2", "m", 0.0783, 0.01),
            ("eps_6_3", "m", 0.0182, 0.01),
            ("g_y", "m/s^2", 0.0, 0.5),
            ("tau", "s", 0.0, 1.0),
            ("gamma_a_zx", "rad", 0.0, 1.5 * deg),
            ("r_a_z", "rad", std::f64::consts::PI, 5.0 * deg),
            ("r_w_x", "rad", 0.0, 5.0 * deg),
            ("k_w_y", "1", 1.0, 0.1),
            ("b_a_z", "m/s^2", 0.0, 2.0),
            ("gamma_w_yz", "rad", 0.0, 2.0 * deg),
            ("b_w_x", "rad/s", 0.0, 5.0 * deg),
        ];
        for (n, unit, nom, sig) in cases {
            let s = get(n);
            assert_eq!(s.unit, unit, "{n}");
            assert!((s.nominal - nom).abs() < 1e-15, "{n}");
            assert!((s.sigma - sig).abs() < 1e-15, "{n}");
        }
        assert_eq!(l.offsets().tau, 23);
        assert_eq!(l.eps_index(6, 3), Some(20));
        assert_eq!(l.eps_index(1, 2), None);
    }

    #[test]
    fn unpack_pack_round_trip_and_fixed_eps() {
        let l = ParamLayout::new(&Robot::aubo_i5());
        let x: Vec<f64> = (0..48).map(|i| 0.01 * i as f64 - 0.2).collect();
        let p = l.unpack(&x).unwrap();
        assert_eq!(l.pack(&p), x);
        assert_eq!(p.eps[1][3], x[4]); // eps_2_4
        assert_eq!(p.eps[0][1], 0.0); // eps_1_2 fixed at 0
        assert_eq!(p.tau, x[23]);
        assert_eq!(p.gyro.b, [x[45], x[46], x[47]]);
        // A robot that does not estimate the IMU position keeps it at the mount.
        let r = Robot::aubo_i5()
            .with_estimated_errors(vec![ErrorIndex { link: 2, k: 4 }])
            .unwrap();
        let l = ParamLayout::new(&r);
        assert_eq!(l.len(), 28);
        let p = l.unpack(&l.nominal()).unwrap();
        assert_eq!(p.eps[5], [0.0252, 0.0783, 0.0182, 0.0, 0.0, 0.0]);
        assert_eq!(
            l.unpack(&[0.0; 3]).unwrap_err(),
            ParamLengthError {
                expected: 28,
                found: 3
            }
        );
    }
}
