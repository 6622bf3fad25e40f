//! Simulated sessions (docs/model.md §7): a ground truth, a joint trajectory and the
//! noise model turned into `joints.csv`, `imu.csv` and `truth.toml`.
//!
//! The simulator promises nothing docs/model.md §4 does not: the two streams have
//! their own rates, start times and optional jitter, and the trajectory's
//! knots need not match the estimator's. Before the trajectory starts and
//! after it ends the robot rests at its end poses, so IMU samples whose
//! t + τ falls outside the motion are still physical (the estimator leaves
//! them out, docs/model.md §4).

use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use robimu_model::params::draw_truth;

use robimu_model::observations::Measurements;
use robimu_model::{
    JointState, MeasurementModel, ModelError, ParamLayout, Robot, Spline, SplineError,
};

/// How to sample a simulated session.
#[derive(Debug, Clone)]
pub struct SimulateOptions {
    /// IMU sample rate, Hz.
    pub imu_rate: f64,
    /// Joint sample rate, Hz.
    pub joint_rate: f64,
    /// Session time of the first IMU sample, s.
    pub imu_start: f64,
    /// Session time of the first joint sample, s.
    pub joint_start: f64,
    /// Standard deviation of the sample-time jitter, s (both streams).
    pub jitter: f64,
    /// Add measurement noise (σ_z, σ_q); off gives noise-free data.
    pub noise: bool,
    /// σ of `[ax, ay, az, gx, gy, gz]`.
    pub sigma_z: [f64; 6],
    /// σ of each joint, rad.
    pub sigma_q: Vec<f64>,
}

impl SimulateOptions {
    /// The paper's setup for `robot`: 120 Hz both streams, its noise.
    pub fn paper(robot: &Robot) -> Self {
        Self {
            imu_rate: 120.0,
            joint_rate: 120.0,
            imu_start: 0.0,
            joint_start: 0.0,
            jitter: 0.0,
            noise: true,
            sigma_z: robot.sigma_z(),
            sigma_q: robot.sigma_q().to_vec(),
        }
    }
}

/// A complete random session from one seed: a truth drawn from the priors, a
/// random trajectory of `duration` s within the joint limits (knots every
/// `knot_spacing` s), and the samples they produce.
pub struct RandomSession {
    /// True x.
    pub truth: Vec<f64>,
    /// The true joint trajectory.
    pub trajectory: Spline,
    /// The samples.
    pub data: Measurements,
}

/// Why a session could not be simulated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimulateError {
    /// The truth is outside the model's domain.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The trajectory could not be built (e.g. a duration shorter than a knot span).
    #[error("cannot build the trajectory: {0}")]
    Trajectory(#[from] SplineError),
}

/// Draw a [`RandomSession`] (see there) for `robot`.
pub fn random_session(
    robot: &Robot,
    duration: f64,
    knot_spacing: f64,
    opts: &SimulateOptions,
    seed: u64,
) -> Result<RandomSession, SimulateError> {
    let layout = ParamLayout::new(robot);
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let truth = draw_truth(&layout, &mut rng);
    let trajectory =
        robimu_model::trajectory::random_walk(robot, duration, knot_spacing, &mut rng)?;
    let data = simulate(robot, &layout, &truth, &trajectory, opts, seed)?;
    Ok(RandomSession {
        truth,
        trajectory,
        data,
    })
}

/// Sample a session: joint samples over the trajectory's span, IMU samples
/// over the same span of the session clock, each IMU sample showing the robot
/// at t + τ (docs/model.md §4).
pub fn simulate(
    robot: &Robot,
    layout: &ParamLayout,
    truth: &[f64],
    trajectory: &Spline,
    opts: &SimulateOptions,
    seed: u64,
) -> Result<Measurements, ModelError> {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed ^ 0x005E_ED0F_5A3F);
    let model = MeasurementModel::new(robot, layout, truth)?;
    let tau = truth[layout.offsets().tau];
    let n = robot.dof();
    let (t0, t1) = (trajectory.knots().start(), trajectory.knots().end());
    let noise = |s: f64, rng: &mut rand::rngs::StdRng| -> f64 {
        if opts.noise {
            let z: f64 = StandardNormal.sample(rng);
            s * z
        } else {
            0.0
        }
    };
    let mut data = Measurements::default();
    let mut js = JointState::default();
    let times = |start: f64, rate: f64, rng: &mut rand::rngs::StdRng| -> Vec<f64> {
        let count = ((t1 - start) * rate).floor().max(0.0) as usize + 1;
        let mut out: Vec<f64> = Vec::with_capacity(count);
        for k in 0..count {
            let jit = if opts.jitter > 0.0 {
                let z: f64 = StandardNormal.sample(rng);
                (opts.jitter * z).clamp(-0.4 / rate, 0.4 / rate)
            } else {
                0.0
            };
            let t = start + k as f64 / rate + jit;
            if t >= t0 && t <= t1 {
                out.push(t);
            }
        }
        out
    };
    data.joint_t = times(opts.joint_start.max(t0), opts.joint_rate, &mut rng);
    for &t in &data.joint_t {
        trajectory.evaluate(t, &mut js).expect("inside the span");
        for j in 0..n {
            data.joint_q
                .push(js.q[j] + noise(opts.sigma_q[j], &mut rng));
        }
    }
    data.imu_t = times(opts.imu_start.max(t0), opts.imu_rate, &mut rng);
    for &t in &data.imu_t {
        trajectory.state_at(t + tau, &mut js);
        let z = model.predict(&js);
        data.imu_z.push(std::array::from_fn(|c| {
            z[c] + noise(opts.sigma_z[c], &mut rng)
        }));
    }
    Ok(data)
}

/// Where the simulated tracker sits: T_tb (robot base in the tracker frame,
/// about 2 m in front of the robot, looking at it) and T_fm (the marker body
/// on the flange). Fixed, so that every simulated session of one setup
/// shares them.
pub fn simulated_registration() -> crate::tracker::Registration {
    use robimu_model::geom::exp_so3;
    crate::tracker::Registration {
        tracker_base: robimu_model::geom::Iso {
            r: exp_so3([0.4, -1.3, 0.9]),
            p: [0.35, -0.2, 2.1],
        },
        flange_marker: robimu_model::geom::Iso {
            r: exp_so3([0.3, 0.5, -0.2]),
            p: [0.045, -0.062, 0.071],
        },
    }
}

/// σ of the simulated tracker: 0.1 mm per position axis, 0.05° per rotation axis.
pub const TRACKER_NOISE: (f64, f64) = (1e-4, 0.05 * std::f64::consts::PI / 180.0);

/// The tracker's measurement of the marker body with the robot at `q` and
/// true parameters `truth` (noise added when `noise`).
pub fn tracker_pose<R: Rng>(
    robot: &Robot,
    flange_eps: &[[f64; 6]],
    q: &[f64],
    noise: bool,
    rng: &mut R,
) -> robimu_model::geom::Iso {
    use crate::tracker::flange_pose;
    use robimu_model::geom::exp_so3;
    let reg = simulated_registration();
    let mut m = reg.predict(&flange_pose(robot, flange_eps, q));
    if noise {
        let mut n3 = |s: f64| -> [f64; 3] {
            std::array::from_fn(|_| {
                let z: f64 = StandardNormal.sample(rng);
                s * z
            })
        };
        let dp = n3(TRACKER_NOISE.0);
        let dr = n3(TRACKER_NOISE.1);
        m.p = robimu_model::geom::add(m.p, dp);
        m.r = robimu_model::geom::mul_mm(&m.r, &exp_so3(dr));
    }
    m
}

/// `count` static poses at configurations drawn uniformly within the joint
/// limits: the tracker's marker pose and the joint readings (with σ_q noise
/// when `opts.noise`), as a tracker would record them for validation.
pub fn static_poses(
    robot: &Robot,
    layout: &ParamLayout,
    truth: &[f64],
    count: usize,
    opts: &SimulateOptions,
    seed: u64,
) -> Result<Vec<crate::tracker::TrackedPose>, ModelError> {
    use crate::tracker::TrackedPose;
    let eps = true_flange_eps(layout, truth)?;
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed ^ 0x7EAC_0E55);
    let mut out = Vec::with_capacity(count);
    for k in 0..count {
        let q: Vec<f64> = robot
            .limits()
            .iter()
            .map(|l| rng.random_range(l.q_min..=l.q_max))
            .collect();
        let marker = tracker_pose(robot, &eps, &q, opts.noise, &mut rng);
        let reading = q
            .iter()
            .zip(&opts.sigma_q)
            .map(|(q, s)| {
                let z: f64 = StandardNormal.sample(&mut rng);
                q + if opts.noise { s * z } else { 0.0 }
            })
            .collect();
        out.push(TrackedPose {
            t: k as f64,
            marker,
            q: reading,
        });
    }
    Ok(out)
}

/// The tracker's marker poses along `trajectory` at `times` (robot clock).
pub fn tracked_motion(
    robot: &Robot,
    layout: &ParamLayout,
    truth: &[f64],
    trajectory: &Spline,
    times: &[f64],
    noise: bool,
    seed: u64,
) -> Result<Vec<robimu_model::geom::Iso>, ModelError> {
    let eps = true_flange_eps(layout, truth)?;
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed ^ 0x0007_AC4E_D000);
    let n = robot.dof();
    let mut js = JointState::default();
    Ok(times
        .iter()
        .map(|&t| {
            trajectory.state_at(t, &mut js);
            tracker_pose(robot, &eps, &js.q[..n], noise, &mut rng)
        })
        .collect())
}

/// The flange's generalized errors of `truth` (the IMU mount row zeroed).
fn true_flange_eps(layout: &ParamLayout, truth: &[f64]) -> Result<Vec<[f64; 6]>, ModelError> {
    let mut eps = layout.unpack(truth)?.eps;
    if let Some(last) = eps.last_mut() {
        *last = [0.0; 6];
    }
    Ok(eps)
}

/// What a simulated tracker records for `robimu validate`.
#[derive(Debug, Clone)]
pub struct TrackerRecording {
    /// The marker pose at every joint sample of the motion (tracker.csv).
    pub motion: Vec<(f64, [f64; 7])>,
    /// Static poses with their joint readings (poses.csv).
    pub poses: Vec<robimu_session::poses::PoseRow>,
}

/// [`tracked_motion`] at the joint sample times of `data` and `count`
/// [`static_poses`], as the rows of their files.
#[allow(clippy::too_many_arguments)]
pub fn tracker_recording(
    robot: &Robot,
    layout: &ParamLayout,
    truth: &[f64],
    trajectory: &Spline,
    data: &Measurements,
    opts: &SimulateOptions,
    count: usize,
    seed: u64,
) -> Result<TrackerRecording, ModelError> {
    use crate::tracker::row_from_pose;
    let markers = tracked_motion(
        robot,
        layout,
        truth,
        trajectory,
        &data.joint_t,
        opts.noise,
        seed,
    )?;
    let motion = data
        .joint_t
        .iter()
        .zip(&markers)
        .map(|(t, m)| (*t, row_from_pose(m)))
        .collect();
    let poses = static_poses(robot, layout, truth, count, opts, seed)?
        .into_iter()
        .map(|p| robimu_session::poses::PoseRow {
            t: p.t,
            pose: row_from_pose(&p.marker),
            q: p.q,
        })
        .collect();
    Ok(TrackerRecording { motion, poses })
}
