//! Joint zero offsets that carry as much of a calibration as a controller's
//! encoder offsets can (the ros2_control export, `robimu export --format
//! ros2-control`).
//!
//! A controller that only adds an offset δ_i to each joint reading moves the
//! nominal flange pose F(q + δ; 0) (eq. (3) with every ε zero) towards the
//! calibrated one F(q; ε̂) (the IMU mount zeroed). The offsets are the least
//! squares fit over the workspace of [`crate::pose_accuracy`] (the same
//! configurations within the joint limits):
//!
//!   δ = argmin Σ_q |p̂(q) − p(q + δ)|² + L² |log(R(q + δ)ᵀ R̂(q))|²,
//!
//! with L = [`ROTATION_LENGTH`] (1 mrad weighs as 0.1 mm: the position
//! error it makes at a tool point 10 cm from the flange), solved by
//! Gauss–Newton with central-difference Jacobians. What the offsets cannot
//! carry (the link geometry's errors: lengths, axis tilts) remains, and is
//! reported as the flange error of the offsets alone against the calibrated
//! model, beside the nominal model's.

use faer::linalg::solvers::Solve;
use faer::{Mat, Side};
use robimu_model::geom::{sub, Iso};
use robimu_model::{ModelParams, ParamLayout, Robot};
use robimu_session::result::PoseErrorStats;

use crate::pose_accuracy::{norm3, rotation_error, stats_of, Workspace};
use crate::tracker::flange_pose;

/// The length that weighs a rotation error against a position error, m/rad.
pub const ROTATION_LENGTH: f64 = 0.1;
/// Central-difference step in the joint angles, rad.
const STEP: f64 = 1e-6;
/// Gauss–Newton iterations (the problem is nearly linear: two suffice to
/// 1e-12 rad for millimetre-sized errors).
const ITERATIONS: usize = 8;

/// The joint offsets of a calibration and what they carry.
#[derive(Debug, Clone, PartialEq)]
pub struct JointOffsets {
    /// δ_i per joint in chain order, rad: the joint angle that the nominal
    /// model needs is the reading plus δ_i.
    pub offsets: Vec<f64>,
    /// The nominal model's flange error against the calibrated one over
    /// the workspace (mean and 95th percentile).
    pub nominal: PoseErrorStats,
    /// The nominal model with the offsets against the calibrated one: what
    /// the offsets leave.
    pub with_offsets: PoseErrorStats,
}

/// The joint offsets that bring `robot`'s nominal flange pose closest to
/// the calibrated one of `params` (module docs).
pub fn joint_offsets(robot: &Robot, params: &ModelParams) -> anyhow::Result<JointOffsets> {
    let n = robot.dof();
    let nominal_eps = vec![[0.0; 6]; params.eps.len()];
    let mut calibrated_eps = params.eps.clone();
    if let Some(last) = calibrated_eps.last_mut() {
        *last = [0.0; 6];
    }
    let workspace = Workspace::new(robot, &ParamLayout::new(robot));
    let configurations = workspace.configurations();
    let target: Vec<Iso> = configurations
        .iter()
        .map(|q| flange_pose(robot, &calibrated_eps, q))
        .collect();
    let pose = |q: &[f64], delta: &[f64]| {
        let shifted: Vec<f64> = q.iter().zip(delta).map(|(a, d)| a + d).collect();
        flange_pose(robot, &nominal_eps, &shifted)
    };
    let residual = |at: &Iso, want: &Iso| -> [f64; 6] {
        let dp = sub(want.p, at.p);
        let dr = rotation_error(at, want);
        std::array::from_fn(|r| {
            if r < 3 {
                dp[r]
            } else {
                ROTATION_LENGTH * dr[r - 3]
            }
        })
    };
    let mut delta = vec![0.0; n];
    for _ in 0..ITERATIONS {
        // normal equations JᵀJ Δ = −Jᵀr of r(δ) = target ⊖ F(q + δ)
        let mut jtj = Mat::<f64>::zeros(n, n);
        let mut jtr = Mat::<f64>::zeros(n, 1);
        for (q, want) in configurations.iter().zip(&target) {
            let r = residual(&pose(q, &delta), want);
            let cols: Vec<[f64; 6]> = (0..n)
                .map(|i| {
                    let (mut plus, mut minus) = (delta.clone(), delta.clone());
                    plus[i] += STEP;
                    minus[i] -= STEP;
                    let (rp, rm) = (
                        residual(&pose(q, &plus), want),
                        residual(&pose(q, &minus), want),
                    );
                    std::array::from_fn(|k| (rp[k] - rm[k]) / (2.0 * STEP))
                })
                .collect();
            for a in 0..n {
                jtr[(a, 0)] += (0..6).map(|k| cols[a][k] * r[k]).sum::<f64>();
                for b in 0..n {
                    jtj[(a, b)] += (0..6).map(|k| cols[a][k] * cols[b][k]).sum::<f64>();
                }
            }
        }
        let step = jtj
            .llt(Side::Lower)
            .map_err(|_| anyhow::anyhow!("the joint offsets are not determined by the flange pose (a joint that does not move the flange?)"))?
            .solve(&jtr);
        let mut largest: f64 = 0.0;
        for (i, d) in delta.iter_mut().enumerate() {
            *d -= step[(i, 0)];
            largest = largest.max(step[(i, 0)].abs());
        }
        if largest < 1e-14 {
            break;
        }
    }
    let errors = |delta: &[f64]| {
        let (mut p, mut r) = (Vec::new(), Vec::new());
        for (q, want) in configurations.iter().zip(&target) {
            let at = pose(q, delta);
            p.push(norm3(&sub(want.p, at.p)));
            r.push(norm3(&rotation_error(&at, want)));
        }
        stats_of(p.into_iter(), r.into_iter())
    };
    Ok(JointOffsets {
        nominal: errors(&vec![0.0; n]),
        with_offsets: errors(&delta),
        offsets: delta,
    })
}

/// The rotation vector of `a`ᵀ`b`, rad.
#[cfg(test)]
mod tests {
    use super::*;

    /// `robot`'s parameters with every kinematic error zero.
    fn zero_errors(robot: &Robot) -> ModelParams {
        let layout = ParamLayout::new(robot);
        let mut params = layout.unpack(&layout.nominal()).unwrap();
        params.eps.iter_mut().for_each(|e| *e = [0.0; 6]);
        params
    }

    /// A calibration whose only error is a joint offset of the first joint:
    /// E_0 is never estimated, so the ε that turns the base about joint 1's
    /// axis is absent; joint 2's offset is ε_1's rotation about z (ε_15)
    /// for the AUBO i5's DH chain. The fit finds it and leaves nothing.
    #[test]
    fn a_pure_joint_offset_is_found_and_leaves_no_error() {
        let robot = Robot::aubo_i5();
        let mut params = zero_errors(&robot);
        // E_1 = Rz(ε_15) right after T_1: the same as joint 2 turned by it
        // when T_2 begins with Rz(q_2) (standard DH)
        params.eps[0][4] = 2e-3;
        let fit = joint_offsets(&robot, &params).unwrap();
        assert!((fit.offsets[1] - 2e-3).abs() < 1e-10, "{:?}", fit.offsets);
        for (i, d) in fit.offsets.iter().enumerate() {
            if i != 1 {
                assert!(d.abs() < 1e-10, "joint {}: {d}", i + 1);
            }
        }
        assert!(
            fit.with_offsets.position_p95_mm < 1e-6,
            "{:?}",
            fit.with_offsets
        );
        assert!(fit.nominal.position_mean_mm > 0.1, "{:?}", fit.nominal);
    }

    /// A length error cannot be carried by offsets: part of the error
    /// remains, and the offsets still reduce the error (never increase it).
    #[test]
    fn a_length_error_remains_in_part() {
        let robot = Robot::aubo_i5();
        let mut params = zero_errors(&robot);
        params.eps[1][0] = 1e-3; // 1 mm along link 2's x
        params.eps[2][3] = 5e-4;
        let fit = joint_offsets(&robot, &params).unwrap();
        assert!(
            fit.with_offsets.position_mean_mm > 0.05,
            "{:?}",
            fit.with_offsets
        );
        assert!(fit.with_offsets.position_mean_mm < fit.nominal.position_mean_mm);
    }

    /// The flange pose is the whole chain's (regression: it once took the
    /// DH part alone, zero for the catalogue's arms): turning a UR5e's base
    /// joint by π at the zero configuration moves tool0 by twice its radius
    /// from joint 1's axis, √((a2 + a3)² + (d4 + d6)²) from UR's published
    /// DH parameters (a2 = −0.425, a3 = −0.3922, d4 = 0.1333, d6 = 0.0996 m).
    #[test]
    fn the_flange_pose_is_the_whole_chain() {
        let robot = Robot::builtin("ur5e").unwrap();
        let eps = vec![[0.0; 6]; 6];
        let a = flange_pose(&robot, &eps, &[0.0; 6]);
        let b = flange_pose(
            &robot,
            &eps,
            &[std::f64::consts::PI, 0.0, 0.0, 0.0, 0.0, 0.0],
        );
        let radius = ((0.425f64 + 0.3922).powi(2) + (0.1333f64 + 0.0996).powi(2)).sqrt();
        assert!(
            (norm3(&sub(a.p, b.p)) - 2.0 * radius).abs() < 1e-9,
            "{:?} {:?}",
            a.p,
            b.p
        );
    }

    /// On a UR5e with errors drawn in every estimated ε, the offsets take
    /// the error down and never up.
    #[test]
    fn offsets_reduce_a_ur5e_error() {
        let robot = Robot::builtin("ur5e").unwrap();
        let mut params = zero_errors(&robot);
        for (i, e) in params.eps.iter_mut().take(5).enumerate() {
            let s = 1e-3 * (i as f64 + 1.0);
            *e = [0.3 * s, -0.2 * s, 0.1 * s, s, -0.7 * s, 0.5 * s];
        }
        let fit = joint_offsets(&robot, &params).unwrap();
        assert!(fit.nominal.position_mean_mm > 1.0, "{:?}", fit.nominal);
        assert!(fit.with_offsets.position_mean_mm < fit.nominal.position_mean_mm);
        assert!(fit.with_offsets.rotation_mean_deg < fit.nominal.rotation_mean_deg);
    }
}
