//! What a calibration buys, in the paper's measure (paper §8.5, Table IV):
//! the flange's position and orientation error over the robot's workspace,
//! predicted before calibration (the prior: the catalogue's or factory
//! model) and after (the posterior), in mm and degrees (docs/model.md §8.7).
//!
//! The workspace is [`CONFIGURATIONS`] joint configurations drawn uniformly
//! within the joint limits (a fixed seed: every calibration of a robot is
//! judged on the same configurations). At each configuration q the flange
//! pose error is linear in the kinematic errors δ of x to first order,
//! e(q) = J(q) δ (J by central differences of the flange pose F(q; ε),
//! eq. (3), with the IMU mount ε_n zeroed; position in the base frame,
//! rotation as the rotation vector of F̂ᵀF), and δ ~ N(0, Σ) with Σ the
//! prior's (diagonal) or the posterior's marginal covariance of the
//! kinematic errors (frozen ones keep their prior σ: they were not
//! estimated). The distribution of |e(q)| is taken from [`DRAWS`] common
//! draws of δ: per configuration its mean and 95th percentile (the band an
//! actual error falls in with 95 % probability), over the workspace the
//! mean and the 95th percentile of all (configuration, draw) pairs.
//!
//! The part of the error after calibration that the data could not reduce
//! is the same prediction with the posterior of the undetermined
//! parameters alone (σ above [`UNDETERMINED`] of the prior σ, or frozen:
//! e.g. the lengths at low speed, paper §8.4). With a known truth
//! (simulation), the actual errors F(q; x̂) against F(q; x_true) beside.

use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use robimu_model::geom::{self, dot, log_so3, mul_mm, sub, Iso};
use robimu_model::{ParamLayout, Robot};
use robimu_session::result::{ActualPoseErrors, PoseAccuracyRecord, PoseErrorStats};

use crate::tracker::flange_pose;
use crate::verdict::UNDETERMINED;

/// Joint configurations of the workspace.
pub(crate) const CONFIGURATIONS: usize = 200;
/// Draws of the kinematic errors per prediction.
pub(crate) const DRAWS: usize = 400;
/// Seed of the configurations and the draws.
const SEED: u64 = 0x005e_ed0f_f1a9;
/// Central-difference step of J, m or rad.
const STEP: f64 = 1e-6;

/// A posterior over x as a calibration reports it.
pub struct Posterior<'a> {
    /// The estimate x̂.
    pub x: &'a [f64],
    /// Posterior σ of each parameter of x (0 when frozen).
    pub sigma: &'a [f64],
    /// Estimated (not frozen) parameters, indices into x.
    pub active: &'a [usize],
    /// Marginal covariance over `active`, row-major.
    pub covariance: &'a [f64],
}

/// The workspace's configurations and the flange pose's sensitivity to the
/// kinematic errors at each.
pub(crate) struct Workspace {
    /// The kinematic errors: indices into x of ε of the links before the IMU mount.
    kinematic: Vec<usize>,
    /// The configurations.
    configurations: Vec<Vec<f64>>,
}

/// Per configuration, the position and rotation error of each draw.
struct Errors {
    /// `[configuration][draw]`, m.
    position: Vec<Vec<f64>>,
    /// `[configuration][draw]`, rad.
    rotation: Vec<Vec<f64>>,
}

impl Workspace {
    /// [`CONFIGURATIONS`] configurations of `robot` within its joint limits.
    pub(crate) fn new(robot: &Robot, layout: &ParamLayout) -> Self {
        let n = layout.n_links();
        let kinematic = layout
            .estimated_errors()
            .iter()
            .enumerate()
            .filter(|(_, e)| e.link < n)
            .map(|(i, _)| i)
            .collect();
        let mut rng = rand::rngs::StdRng::seed_from_u64(SEED);
        let configurations = (0..CONFIGURATIONS)
            .map(|_| {
                robot
                    .limits()
                    .iter()
                    .map(|l| l.q_min + (l.q_max - l.q_min) * rng.random::<f64>())
                    .collect()
            })
            .collect();
        Self {
            kinematic,
            configurations,
        }
    }

    /// The configurations (joint angles, rad).
    pub(crate) fn configurations(&self) -> &[Vec<f64>] {
        &self.configurations
    }

    /// The number of configurations.
    pub(crate) fn len(&self) -> usize {
        self.configurations.len()
    }

    /// The flange pose at configuration `c` under x.
    fn pose(&self, robot: &Robot, layout: &ParamLayout, x: &[f64], c: usize) -> Iso {
        flange_pose(robot, &flange_eps(layout, x), &self.configurations[c])
    }

    /// J(q) at x for each configuration: 6 rows (position, rotation) by
    /// the kinematic errors.
    fn jacobians(&self, robot: &Robot, layout: &ParamLayout, x: &[f64]) -> Vec<Vec<[f64; 6]>> {
        (0..self.len())
            .map(|c| {
                let at = self.pose(robot, layout, x, c);
                self.kinematic
                    .iter()
                    .map(|&k| {
                        let mut xp = x.to_vec();
                        xp[k] += STEP;
                        let plus = self.pose(robot, layout, &xp, c);
                        xp[k] -= 2.0 * STEP;
                        let minus = self.pose(robot, layout, &xp, c);
                        let dp = sub(plus.p, minus.p);
                        let dr = sub(rotation_error(&at, &plus), rotation_error(&at, &minus));
                        std::array::from_fn(|r| {
                            (if r < 3 { dp[r] } else { dr[r - 3] }) / (2.0 * STEP)
                        })
                    })
                    .collect()
            })
            .collect()
    }

    /// The errors of [`DRAWS`] draws δ ~ N(0, Σ) (`cov` over the kinematic
    /// errors, row-major) at each configuration, linearised at x.
    fn predicted(&self, robot: &Robot, layout: &ParamLayout, x: &[f64], cov: &[f64]) -> Errors {
        let m = self.kinematic.len();
        let l = cholesky_psd(cov, m);
        let mut rng = rand::rngs::StdRng::seed_from_u64(SEED ^ 0xd4a5);
        let draws: Vec<Vec<f64>> = (0..DRAWS)
            .map(|_| {
                let z: Vec<f64> = (0..m).map(|_| StandardNormal.sample(&mut rng)).collect();
                (0..m)
                    .map(|i| (0..=i).map(|j| l[i * m + j] * z[j]).sum())
                    .collect()
            })
            .collect();
        let jac = self.jacobians(robot, layout, x);
        let mut e = Errors {
            position: Vec::with_capacity(self.len()),
            rotation: Vec::with_capacity(self.len()),
        };
        for j in &jac {
            let (mut p, mut r) = (Vec::with_capacity(DRAWS), Vec::with_capacity(DRAWS));
            for d in &draws {
                let v: [f64; 6] =
                    std::array::from_fn(|row| j.iter().zip(d).map(|(c, di)| c[row] * di).sum());
                p.push(norm3(&v[..3]));
                r.push(norm3(&v[3..]));
            }
            e.position.push(p);
            e.rotation.push(r);
        }
        e
    }

    /// The actual errors of x̂ against `truth` at each configuration, m and rad.
    fn actual(
        &self,
        robot: &Robot,
        layout: &ParamLayout,
        x_hat: &[f64],
        truth: &[f64],
    ) -> (Vec<f64>, Vec<f64>) {
        (0..self.len())
            .map(|c| {
                let (est, tru) = (
                    self.pose(robot, layout, x_hat, c),
                    self.pose(robot, layout, truth, c),
                );
                let dp = sub(est.p, tru.p);
                (dot(dp, dp).sqrt(), norm3(&rotation_error(&tru, &est)))
            })
            .unzip()
    }
}

/// The pose accuracy of a calibration (module doc): `posterior` over x of
/// `layout` (any number of IMUs: the robot's errors are shared); `truth`
/// (simulation) adds the actual errors.
pub fn pose_accuracy(
    robot: &Robot,
    layout: &ParamLayout,
    posterior: &Posterior<'_>,
    truth: Option<&[f64]>,
) -> PoseAccuracyRecord {
    let one = layout.imu_layout();
    let ws = Workspace::new(robot, one);
    // the kinematic errors' indices in the full x
    let full: Vec<usize> = ws.kinematic.iter().map(|&k| layout.imu_map(0)[k]).collect();
    let specs = layout.specs();
    let m = full.len();
    let prior_sd = |k: usize| specs[k].sigma;
    let mut before = vec![0.0; m * m];
    for (i, &k) in full.iter().enumerate() {
        before[i * m + i] = prior_sd(k) * prior_sd(k);
    }
    let after = posterior_block(posterior, &full, &prior_sd);
    let undetermined: Vec<bool> = full
        .iter()
        .map(|&k| !posterior.active.contains(&k) || posterior.sigma[k] > UNDETERMINED * prior_sd(k))
        .collect();
    let mut left = after.clone();
    for i in 0..m {
        for j in 0..m {
            if !(undetermined[i] && undetermined[j]) {
                left[i * m + j] = 0.0;
            }
        }
    }
    let nominal = one.nominal();
    let x_hat = layout.imu_x(0, posterior.x);
    let before_e = ws.predicted(robot, one, &nominal, &before);
    let after_e = ws.predicted(robot, one, &x_hat, &after);
    let left_e = ws.predicted(robot, one, &x_hat, &left);
    let actual = |x: &[f64], band: &Errors, truth: &[f64]| {
        let (p, r) = ws.actual(robot, one, x, &layout.imu_x(0, truth));
        ActualPoseErrors {
            stats: stats_of(p.iter().copied(), r.iter().copied()),
            position_inside_band: inside(&p, &band.position),
            rotation_inside_band: inside(&r, &band.rotation),
        }
    };
    PoseAccuracyRecord {
        configurations: ws.len(),
        before: summary(&before_e),
        after: summary(&after_e),
        after_undetermined: summary(&left_e),
        actual_before: truth.map(|t| actual(&nominal, &before_e, t)),
        actual_after: truth.map(|t| actual(&x_hat, &after_e, t)),
    }
}

/// Σ of the kinematic errors `kin` from the posterior: the marginal
/// covariance of the active ones, the prior variance of the frozen ones.
fn posterior_block(p: &Posterior<'_>, kin: &[usize], prior_sd: &dyn Fn(usize) -> f64) -> Vec<f64> {
    let (m, na) = (kin.len(), p.active.len());
    let pos: Vec<Option<usize>> = kin
        .iter()
        .map(|k| p.active.iter().position(|a| a == k))
        .collect();
    let mut cov = vec![0.0; m * m];
    for i in 0..m {
        for j in 0..m {
            cov[i * m + j] = match (pos[i], pos[j]) {
                (Some(a), Some(b)) => p.covariance[a * na + b],
                _ if i == j => prior_sd(kin[i]).powi(2),
                _ => 0.0,
            };
        }
    }
    cov
}

/// ε of x with the IMU mount (the last link's) zeroed: the flange's.
fn flange_eps(layout: &ParamLayout, x: &[f64]) -> Vec<[f64; 6]> {
    let mut eps = layout.fixed_eps().to_vec();
    for (i, e) in layout.estimated_errors().iter().enumerate() {
        eps[e.link - 1][e.k - 1] = x[i];
    }
    if let Some(last) = eps.last_mut() {
        *last = [0.0; 6];
    }
    eps
}

/// The rotation vector of `a`ᵀ`b`, rad.
/// The rotation vector Log(aᵀ b) from pose `a`'s orientation to `b`'s.
pub(crate) fn rotation_error(a: &Iso, b: &Iso) -> [f64; 3] {
    log_so3(&mul_mm(&geom::transpose(&a.r), &b.r))
}

/// Euclidean norm.
pub(crate) fn norm3(v: &[f64]) -> f64 {
    v.iter().map(|a| a * a).sum::<f64>().sqrt()
}

/// Lower Cholesky factor of the symmetric positive semidefinite `a` (m×m,
/// row-major); a column whose pivot is not positive is left zero.
fn cholesky_psd(a: &[f64], m: usize) -> Vec<f64> {
    let mut l: Vec<f64> = vec![0.0; m * m];
    for j in 0..m {
        let d = a[j * m + j] - (0..j).map(|k| l[j * m + k].powi(2)).sum::<f64>();
        if d <= 1e-300 {
            continue;
        }
        let djj = d.sqrt();
        l[j * m + j] = djj;
        for i in j + 1..m {
            let s = a[i * m + j] - (0..j).map(|k| l[i * m + k] * l[j * m + k]).sum::<f64>();
            l[i * m + j] = s / djj;
        }
    }
    l
}

/// The share of `actual[c]` at or below the 95th percentile of `band[c]`.
fn inside(actual: &[f64], band: &[Vec<f64>]) -> f64 {
    let n = actual.len().max(1) as f64;
    actual
        .iter()
        .zip(band)
        .filter(|(a, b)| **a <= percentile(b, 0.95))
        .count() as f64
        / n
}

/// The `p`-quantile of `v` (nearest rank).
fn percentile(v: &[f64], p: f64) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let k = ((p * s.len() as f64).ceil() as usize).clamp(1, s.len().max(1)) - 1;
    s.get(k).copied().unwrap_or(0.0)
}

/// Mean and 95th percentile over every (configuration, draw).
fn summary(e: &Errors) -> PoseErrorStats {
    stats_of(
        e.position.iter().flatten().copied(),
        e.rotation.iter().flatten().copied(),
    )
}

/// Mean and 95th percentile of position (m) and rotation (rad) errors, in
/// mm and degrees.
pub(crate) fn stats_of(
    p: impl Iterator<Item = f64>,
    r: impl Iterator<Item = f64>,
) -> PoseErrorStats {
    let (p, r): (Vec<f64>, Vec<f64>) = (p.collect(), r.collect());
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    PoseErrorStats {
        position_mean_mm: 1e3 * mean(&p),
        position_p95_mm: 1e3 * percentile(&p, 0.95),
        rotation_mean_deg: mean(&r).to_degrees(),
        rotation_p95_deg: percentile(&r, 0.95).to_degrees(),
    }
}

/// Draws a truth from the priors (tests and Monte Carlo): kept here beside
/// the prediction it checks.
#[cfg(test)]
fn draw_truth(layout: &ParamLayout, seed: u64) -> Vec<f64> {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    robimu_model::params::draw_truth(layout, &mut rng)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// J by central differences against the exact first-order change of
    /// the pose: a small δ moves the pose by J δ to second order.
    #[test]
    fn jacobian_predicts_small_moves() {
        let robot = Robot::aubo_i5();
        let layout = ParamLayout::new(&robot);
        let ws = Workspace::new(&robot, &layout);
        let x = layout.nominal();
        let jac = ws.jacobians(&robot, &layout, &x);
        let mut delta = vec![0.0; layout.len()];
        for (i, &k) in ws.kinematic.iter().enumerate() {
            delta[k] = 1e-5 * (1.0 + i as f64 % 3.0) * if i % 2 == 0 { 1.0 } else { -1.0 };
        }
        let xd: Vec<f64> = x.iter().zip(&delta).map(|(a, b)| a + b).collect();
        for c in [0, 17, 199] {
            let (a, b) = (
                ws.pose(&robot, &layout, &x, c),
                ws.pose(&robot, &layout, &xd, c),
            );
            let dp = sub(b.p, a.p);
            let dr = rotation_error(&a, &b);
            for row in 0..6 {
                let lin: f64 = ws
                    .kinematic
                    .iter()
                    .enumerate()
                    .map(|(i, &k)| jac[c][i][row] * delta[k])
                    .sum();
                let got = if row < 3 { dp[row] } else { dr[row - 3] };
                assert!(
                    (lin - got).abs() < 1e-8,
                    "config {c} row {row}: {lin} vs {got}"
                );
            }
        }
    }

    /// Before calibration the prediction is the prior's: truths drawn from
    /// the priors land inside the predicted 95 % band at 95 % of the
    /// configurations (±3 %), and the predicted mean is the measured one
    /// within 10 %, over 40 truths × 200 configurations.
    #[test]
    fn prior_prediction_matches_truths_from_the_prior() {
        let robot = Robot::aubo_i5();
        let layout = ParamLayout::new(&robot);
        let nominal = layout.nominal();
        let sigma: Vec<f64> = vec![0.0; layout.len()];
        // (the truth's IMU parameters do not move the flange)
        let none = Posterior {
            x: &nominal,
            sigma: &sigma,
            active: &[],
            covariance: &[],
        };
        let (mut inside_p, mut inside_r, mut mean_p, mut mean_r) = (0.0, 0.0, 0.0, 0.0);
        let runs = 40;
        let mut predicted = None;
        for seed in 0..runs {
            let truth = draw_truth(&layout, seed);
            let a = pose_accuracy(&robot, &layout, &none, Some(&truth));
            let before = a.actual_before.unwrap();
            inside_p += before.position_inside_band / runs as f64;
            inside_r += before.rotation_inside_band / runs as f64;
            mean_p += before.stats.position_mean_mm / runs as f64;
            mean_r += before.stats.rotation_mean_deg / runs as f64;
            // nothing estimated: after is before, all of it undetermined
            assert_eq!(
                a.after.position_mean_mm,
                a.after_undetermined.position_mean_mm
            );
            predicted = Some(a.before);
        }
        let predicted = predicted.unwrap();
        println!(
            "inside: {inside_p:.3} / {inside_r:.3}; mean {mean_p:.3} mm vs {:.3}, {mean_r:.4}° vs {:.4}",
            predicted.position_mean_mm, predicted.rotation_mean_deg
        );
        assert!((0.92..=0.98).contains(&inside_p), "{inside_p}");
        assert!((0.92..=0.98).contains(&inside_r), "{inside_r}");
        assert!((mean_p / predicted.position_mean_mm - 1.0).abs() < 0.1);
        assert!((mean_r / predicted.rotation_mean_deg - 1.0).abs() < 0.1);
    }

    #[test]
    fn cholesky_of_a_known_matrix() {
        // [[4, 2], [2, 3]] = L Lᵀ with L = [[2, 0], [1, √2]]
        let l = cholesky_psd(&[4.0, 2.0, 2.0, 3.0], 2);
        assert_eq!(l[0], 2.0);
        assert_eq!(l[2], 1.0);
        assert!((l[3] - 2f64.sqrt()).abs() < 1e-15);
        // semidefinite: the zero column stays zero
        let l = cholesky_psd(&[0.0, 0.0, 0.0, 9.0], 2);
        assert_eq!(l, vec![0.0, 0.0, 0.0, 3.0]);
    }
}
