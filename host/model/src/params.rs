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
pub(crate) const PARAM_GROUPS: &[&str] = &["lengths"];

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

/// The layout of x for one robot and K ≥ 1 IMUs (docs/model.md §5, §9).
///
/// With K = 1 x is the 48-vector of §5. With K > 1 IMU 0's parameters keep
/// the §5 names in the §5 order (the first [`Self::imu_layout`]`.len()`
/// entries), then each IMU j ≥ 1 appends its own ones — its position
/// ε_n1..3 (where estimated), τ and 24 sensor parameters, named
/// `imu<j>/<name>` — with the same priors except the mount's: IMU j's
/// position and rotation priors are [`Robot::mount_of`]`(j)` (where the
/// position is not estimated it is fixed at IMU 0's). Every IMU's own vector (the
/// one-IMU layout, which [`crate::MeasurementModel`] takes) maps into x by
/// [`Self::imu_map`]; for K = 1 that map is the identity. [`Self::offsets`],
/// [`Self::unpack`] and [`Self::eps_index`] describe IMU 0 (the prefix).
#[derive(Clone, Debug, PartialEq)]
pub struct ParamLayout {
    specs: Vec<ParamSpec>,
    estimated: Vec<ErrorIndex>,
    fixed_eps: Vec<[f64; 6]>,
    offsets: Offsets,
    /// `imu_maps[j][k]`: index in x of entry k of IMU j's one-IMU vector.
    imu_maps: Vec<Vec<usize>>,
    /// The one-IMU layout when K > 1 (None: this layout is it).
    single: Option<Box<ParamLayout>>,
}

const XYZ: [&str; 3] = ["x", "y", "z"];
const ZYX: [&str; 3] = ["z", "y", "x"];
const GAMMA: [&str; 3] = ["yz", "zy", "zx"];

impl ParamLayout {
    /// The layout for `robot`: its estimated ε set and its priors.
    pub fn new(robot: &Robot) -> Self {
        Self::for_mount(robot, robot.mount())
    }

    /// [`Self::new`] with `mount` as the IMU's mount prior (the position
    /// ε_n1..3 and the rotations r_a, r_ω: prior means and σ).
    fn for_mount(robot: &Robot, mount: &crate::robot::ImuMount) -> Self {
        let n = robot.dof();
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
            imu_maps: vec![(0..specs.len()).collect()],
            specs,
            estimated,
            fixed_eps,
            offsets,
            single: None,
        }
    }

    /// The layout for `robot` with `n_imus` IMUs (docs/model.md §9; see the
    /// type's doc): 20 + 28K entries for a 6R arm; `n_imus = 1` is
    /// [`Self::new`].
    ///
    /// # Panics
    /// If `n_imus` is 0.
    pub fn with_imus(robot: &Robot, n_imus: usize) -> Self {
        assert!(n_imus >= 1, "a layout needs at least one IMU");
        let one = Self::new(robot);
        if n_imus == 1 {
            return one;
        }
        let mut specs = one.specs.clone();
        let mut imu_maps = vec![(0..one.len()).collect::<Vec<_>>()];
        for j in 1..n_imus {
            // IMU j's own mount prior ([`Robot::mount_of`]); the rest as IMU 0's
            let own = Self::for_mount(robot, robot.mount_of(j));
            let map = (0..one.len())
                .map(|k| {
                    if one.is_per_imu(k) {
                        let s = &own.specs[k];
                        specs.push(ParamSpec {
                            name: format!("imu{j}/{}", s.name),
                            ..s.clone()
                        });
                        specs.len() - 1
                    } else {
                        k
                    }
                })
                .collect();
            imu_maps.push(map);
        }
        Self {
            specs,
            estimated: one.estimated.clone(),
            fixed_eps: one.fixed_eps.clone(),
            offsets: one.offsets,
            imu_maps,
            single: Some(Box::new(one)),
        }
    }

    /// The number of IMUs K whose layout for `robot` has `len` entries (None
    /// when no K ≥ 1 has).
    pub fn imus_for_len(robot: &Robot, len: usize) -> Option<usize> {
        let one = Self::new(robot);
        let own = (0..one.len()).filter(|&k| one.is_per_imu(k)).count();
        let extra = len.checked_sub(one.len())?;
        (extra % own == 0).then_some(1 + extra / own)
    }

    /// Whether entry `k` of the one-IMU vector belongs to one IMU (its
    /// position ε_n1..3, τ, the sensor parameters) rather than being shared
    /// (the other robot errors, g_x, g_y; docs/model.md §9).
    pub fn is_per_imu(&self, k: usize) -> bool {
        let n = self.n_links();
        match self.estimated.get(k) {
            Some(e) => e.link == n && e.is_translation(),
            None => k >= self.offsets.tau && k < self.offsets.len,
        }
    }

    /// Number of IMUs K.
    pub fn n_imus(&self) -> usize {
        self.imu_maps.len()
    }

    /// The layout of one IMU's own vector (the §5 one-IMU layout; `self`
    /// when K = 1).
    pub fn imu_layout(&self) -> &ParamLayout {
        self.single.as_deref().unwrap_or(self)
    }

    /// Index in x of each entry of IMU `j`'s own vector ([`Self::imu_layout`]
    /// order).
    ///
    /// # Panics
    /// If `j ≥ self.n_imus()`.
    pub fn imu_map(&self, j: usize) -> &[usize] {
        &self.imu_maps[j]
    }

    /// IMU `j`'s own vector taken from the full `x`.
    pub fn imu_x(&self, j: usize, x: &[f64]) -> Vec<f64> {
        self.imu_maps[j].iter().map(|&k| x[k]).collect()
    }

    /// Index in x of IMU `j`'s parameter named `name` in §5 (`tau`, `k_a_x`, …).
    pub fn imu_index(&self, j: usize, name: &str) -> Option<usize> {
        let k = self.imu_layout().index_of(name)?;
        self.imu_maps.get(j).map(|m| m[k])
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

    /// Typed view of `x` (IMU 0's parameters when K > 1).
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

    /// The one-IMU x from a typed view (ε outside the estimated set are
    /// dropped; [`Self::imu_layout`] order).
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

    #[test]
    fn several_imus_share_the_robot_and_gravity() {
        let robot = Robot::aubo_i5();
        let one = ParamLayout::new(&robot);
        assert_eq!(ParamLayout::with_imus(&robot, 1), one);
        assert_eq!(one.imu_map(0), (0..48).collect::<Vec<_>>());
        let l = ParamLayout::with_imus(&robot, 3);
        assert_eq!(l.len(), 20 + 28 * 3);
        assert_eq!(ParamLayout::imus_for_len(&robot, 104), Some(3));
        assert_eq!(ParamLayout::imus_for_len(&robot, 48), Some(1));
        assert_eq!(ParamLayout::imus_for_len(&robot, 50), None);
        assert_eq!(l.n_imus(), 3);
        assert_eq!(l.imu_layout(), &one);
        // IMU 0 is the §5 vector, in its order, as the prefix
        assert_eq!(&l.specs()[..48], one.specs());
        let names: Vec<&str> = l.specs()[48..51].iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names, ["imu1/eps_6_1", "imu1/eps_6_2", "imu1/eps_6_3"]);
        assert_eq!(l.specs()[51].name, "imu1/tau");
        assert_eq!(l.specs()[76].name, "imu2/eps_6_1");
        assert_eq!(l.specs().last().unwrap().name, "imu2/b_w_z");
        // each IMU's map: the shared entries at IMU 0's index, its own ones
        // at its names, with the §5 priors
        for j in 0..3 {
            let map = l.imu_map(j);
            for (k, s) in one.specs().iter().enumerate() {
                let full = &l.specs()[map[k]];
                let want = if j == 0 || !one.is_per_imu(k) {
                    s.name.clone()
                } else {
                    format!("imu{j}/{}", s.name)
                };
                assert_eq!(full.name, want);
                assert_eq!(
                    (full.unit, full.nominal, full.sigma),
                    (s.unit, s.nominal, s.sigma)
                );
            }
        }
        let shared: Vec<&str> = (0..48)
            .filter(|&k| !one.is_per_imu(k))
            .map(|k| one.specs()[k].name.as_str())
            .collect();
        assert_eq!(shared.len(), 20);
        assert!(shared.contains(&"g_y") && shared.contains(&"eps_5_6"));
        assert!(!shared.contains(&"eps_6_1") && !shared.contains(&"tau"));
        assert_eq!(l.imu_index(2, "tau"), l.index_of("imu2/tau"));
        assert_eq!(l.imu_index(1, "g_x"), l.index_of("g_x"));
        let x: Vec<f64> = (0..l.len()).map(|i| i as f64).collect();
        assert_eq!(l.imu_x(1, &x)[23], 51.0);
        assert_eq!(
            l.select(&["imu1/k_a_x"]).unwrap(),
            vec![l.index_of("imu1/k_a_x").unwrap()]
        );
    }

    #[test]
    fn an_imu_with_its_own_mount_has_its_own_position_and_rotation_priors() {
        let robot = Robot::aubo_i5();
        let mut m = *robot.mount();
        m.position = [0.1, -0.05, 0.02];
        m.position_sigma = 0.002;
        m.r_a = [0.0, 0.1, 0.0];
        m.rotation_sigma = 0.01;
        let moved = robot.with_mount(2, m).unwrap();
        assert_eq!(moved.mount_of(2), &m);
        assert_eq!(moved.mount_of(1), robot.mount());
        let (base, l) = (
            ParamLayout::with_imus(&robot, 3),
            ParamLayout::with_imus(&moved, 3),
        );
        for (k, (a, b)) in base.specs().iter().zip(l.specs()).enumerate() {
            let want = match b.name.as_str() {
                "imu2/eps_6_1" => (0.1, 0.002),
                "imu2/eps_6_2" => (-0.05, 0.002),
                "imu2/eps_6_3" => (0.02, 0.002),
                "imu2/r_a_z" | "imu2/r_a_x" => (0.0, 0.01),
                "imu2/r_a_y" => (0.1, 0.01),
                "imu2/r_w_z" => (robot.mount().r_w[0], 0.01),
                "imu2/r_w_y" | "imu2/r_w_x" => (0.0, 0.01),
                _ => (a.nominal, a.sigma),
            };
            assert_eq!((b.nominal, b.sigma), want, "{k} {}", b.name);
        }
        // IMU 0's own mount is the robot's
        let zero = robot.with_mount(0, m).unwrap();
        assert_eq!(ParamLayout::new(&zero).specs()[18].nominal, 0.1);
        m.position_sigma = 0.0;
        let e = robot.with_mount(1, m).unwrap_err().to_string();
        assert!(e.contains("imu1.mount.position_sigma"), "{e}");
    }
}
