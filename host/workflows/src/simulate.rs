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

use robimu_model::noise::{NoiseModel, NoiseSampler};
use robimu_model::observations::{ImuSamples, Measurements};
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
    /// The IMU noise when it is not white (docs/model.md §4.6): correlated
    /// in time and following the motion; its σ replace `sigma_z`. `None`:
    /// white noise of σ `sigma_z` (the paper's model).
    pub noise_model: Option<NoiseModel>,
    /// Each IMU's own noise (docs/model.md §9): IMU j's is `imu_noise[j]`
    /// when the list has one for it (its σ replace `sigma_z`), else
    /// `noise_model` (or white of `sigma_z`). Empty: every IMU alike.
    pub imu_noise: Vec<NoiseModel>,
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
            noise_model: None,
            imu_noise: Vec::new(),
        }
    }

    /// The noise model IMU `j` is simulated with (`None`: white of `sigma_z`).
    pub fn noise_of(&self, j: usize) -> Option<&NoiseModel> {
        self.imu_noise.get(j).or(self.noise_model.as_ref())
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

/// A sensor warm-up: T(t) = T_end + (T_start − T_end)·e^{−(t − t_0)/τ}, t_0
/// the first IMU sample (the recording's `temp_c` column, and the curve the
/// biases of `temperature_bias` follow in `simulate --temperature`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WarmUpTemperature {
    /// T at t_0, °C.
    pub start_c: f64,
    /// T once warm, °C.
    pub end_c: f64,
    /// τ, s.
    pub time_constant_s: f64,
}

/// The BNO055's temperature LSB, °C (`TEMP` register, datasheet §3.6.5.8).
pub(crate) const TEMPERATURE_LSB: f64 = 1.0;

impl WarmUpTemperature {
    /// A warm-up, refused unless the temperatures are finite and τ > 0.
    pub fn new(start_c: f64, end_c: f64, time_constant_s: f64) -> Result<Self, String> {
        if !(start_c.is_finite() && end_c.is_finite()) {
            return Err(format!(
                "the temperatures must be finite numbers (got {start_c}, {end_c})"
            ));
        }
        if !(time_constant_s.is_finite() && time_constant_s > 0.0) {
            return Err(format!(
                "the time constant must be a positive number of seconds (got {time_constant_s})"
            ));
        }
        Ok(Self {
            start_c,
            end_c,
            time_constant_s,
        })
    }

    /// T at `dt` seconds after the first sample, °C.
    pub fn at(&self, dt: f64) -> f64 {
        self.end_c + (self.start_c - self.end_c) * (-dt.max(0.0) / self.time_constant_s).exp()
    }

    /// The true T at the IMU times `imu_t`.
    pub fn values(&self, imu_t: &[f64]) -> Vec<f64> {
        let t0 = imu_t.first().copied().unwrap_or(0.0);
        imu_t.iter().map(|t| self.at(t - t0)).collect()
    }

    /// What the chip reports at `imu_t`: T rounded to [`TEMPERATURE_LSB`].
    pub fn readings(&self, imu_t: &[f64]) -> Vec<f64> {
        self.values(imu_t)
            .into_iter()
            .map(|v| (v / TEMPERATURE_LSB).round() * TEMPERATURE_LSB)
            .collect()
    }
}

/// Draw a [`RandomSession`] (see there) for `robot`.
pub fn random_session(
    robot: &Robot,
    duration: f64,
    knot_spacing: f64,
    opts: &SimulateOptions,
    seed: u64,
) -> Result<RandomSession, SimulateError> {
    random_session_imus(robot, 1, duration, knot_spacing, opts, seed)
}

/// [`random_session`] with `n_imus` IMUs on the flange (docs/model.md §9):
/// the truth of [`ParamLayout::with_imus`] drawn from its priors (each
/// IMU's 28 its own draws), one robot motion seen by every IMU. One IMU
/// gives exactly [`random_session`].
pub fn random_session_imus(
    robot: &Robot,
    n_imus: usize,
    duration: f64,
    knot_spacing: f64,
    opts: &SimulateOptions,
    seed: u64,
) -> Result<RandomSession, SimulateError> {
    let layout = ParamLayout::with_imus(robot, n_imus);
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
/// at t + τ (docs/model.md §4). A layout of K IMUs ([`ParamLayout::with_imus`])
/// samples each IMU at its own parameters (its τ, position, intrinsics), on
/// its own sample times and noise, into `imu_*` and `extra_imus` (§9).
pub fn simulate(
    robot: &Robot,
    layout: &ParamLayout,
    truth: &[f64],
    trajectory: &Spline,
    opts: &SimulateOptions,
    seed: u64,
) -> Result<Measurements, ModelError> {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed ^ 0x005E_ED0F_5A3F);
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
    for j in 0..layout.n_imus() {
        let own = layout.imu_x(j, truth);
        let model = MeasurementModel::new(robot, layout.imu_layout(), &own)?;
        let tau = own[layout.imu_layout().offsets().tau];
        let imu_t = times(opts.imu_start.max(t0), opts.imu_rate, &mut rng);
        let mut imu_z = Vec::with_capacity(imu_t.len());
        // The IMU stream is one segment: the correlated noise runs along it.
        let mut sampler = opts.noise_of(j).cloned().map(NoiseSampler::new);
        for &t in &imu_t {
            trajectory.state_at(t + tau, &mut js);
            let z = model.predict(&js);
            match sampler.as_mut().filter(|_| opts.noise) {
                None => imu_z.push(std::array::from_fn(|c| {
                    z[c] + noise(opts.sigma_z[c], &mut rng)
                })),
                Some(sampler) => {
                    let e: [f64; 6] = std::array::from_fn(|_| StandardNormal.sample(&mut rng));
                    let qdd2: f64 = js.qdd[..n].iter().map(|a| a * a).sum();
                    let w = sampler.next(e, qdd2);
                    imu_z.push(std::array::from_fn(|c| z[c] + w[c]));
                }
            }
        }
        if j == 0 {
            (data.imu_t, data.imu_z) = (imu_t, imu_z);
        } else {
            data.extra_imus.push(ImuSamples {
                t: imu_t,
                z: imu_z,
                temp: None,
            });
        }
    }
    Ok(data)
}

/// The bias drift the paper observed over [`PAPER_DRIFT_TIME`] (25 min),
/// per channel: 0.017 m/s² on each accelerometer axis, 0.025 °/s on each
/// gyroscope axis (docs/model.md §4.7).
pub(crate) const PAPER_DRIFT: [f64; 6] = [
    0.017,
    0.017,
    0.017,
    0.025 * std::f64::consts::PI / 180.0,
    0.025 * std::f64::consts::PI / 180.0,
    0.025 * std::f64::consts::PI / 180.0,
];

/// The time over which the paper observed [`PAPER_DRIFT`], s.
pub(crate) const PAPER_DRIFT_TIME: f64 = 1500.0;

/// A seeded Brownian bias per IMU channel at the samples `t` (ascending):
/// independent random walks whose standard deviation after
/// [`PAPER_DRIFT_TIME`] is `scale` × [`PAPER_DRIFT`], i.e. increments
/// N(0, (scale·D_c)² Δt / 1500 s), exact at any sample spacing; then
/// centred on the session (its mean over the samples subtracted), so that
/// the constant biases of the truth are the session-mean biases. Not the
/// estimator's bias spline: any path, at the samples' own resolution.
pub fn bias_walk(t: &[f64], scale: f64, seed: u64) -> Vec<[f64; 6]> {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed ^ 0x0B1A_5DA1_C0DE);
    let mut w = [0.0; 6];
    let mut prev = t.first().copied().unwrap_or(0.0);
    let mut out: Vec<[f64; 6]> = t
        .iter()
        .map(|&ti| {
            let dt = (ti - prev).max(0.0);
            prev = ti;
            for c in 0..6 {
                let e: f64 = StandardNormal.sample(&mut rng);
                w[c] += scale * PAPER_DRIFT[c] * (dt / PAPER_DRIFT_TIME).sqrt() * e;
            }
            w
        })
        .collect();
    let n = out.len().max(1) as f64;
    let mean: [f64; 6] = std::array::from_fn(|c| out.iter().map(|v| v[c]).sum::<f64>() / n);
    for v in &mut out {
        for c in 0..6 {
            v[c] -= mean[c];
        }
    }
    out
}

/// Add [`bias_walk`] to the IMU samples of `data`; the walk added.
pub fn add_bias_walk(data: &mut Measurements, scale: f64, seed: u64) -> Vec<[f64; 6]> {
    let walk = bias_walk(&data.imu_t, scale, seed);
    for (z, w) in data.imu_z.iter_mut().zip(&walk) {
        for c in 0..6 {
            z[c] += w[c];
        }
    }
    walk
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
pub(crate) const TRACKER_NOISE: (f64, f64) = (1e-4, 0.05 * std::f64::consts::PI / 180.0);

/// The tracker's measurement of the marker body with the robot at `q` and
/// true parameters `truth` (noise added when `noise`).
pub(crate) fn tracker_pose<R: Rng>(
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
pub(crate) struct TrackerRecording {
    /// The marker pose at every joint sample of the motion (tracker.csv).
    pub motion: Vec<(f64, [f64; 7])>,
    /// Static poses with their joint readings (poses.csv).
    pub poses: Vec<robimu_session::poses::PoseRow>,
}

/// [`tracked_motion`] at the joint sample times of `data` and `count`
/// [`static_poses`], as the rows of their files.
#[allow(clippy::too_many_arguments)]
pub(crate) fn tracker_recording(
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

#[cfg(test)]
mod tests {
    use super::*;
    use robimu_model::noise::{ArNoise, ChannelNoise};

    /// A random session, and its IMU noise under `model`: the same truth and
    /// trajectory simulated with the model, minus without noise; plus
    /// ‖q̈(t + τ)‖² at each IMU sample.
    fn noise_of(model: Option<NoiseModel>, duration: f64, seed: u64) -> (Vec<[f64; 6]>, Vec<f64>) {
        let robot = Robot::aubo_i5();
        let layout = ParamLayout::new(&robot);
        let base = SimulateOptions::paper(&robot);
        let s = random_session(&robot, duration, 1.0, &base, seed).unwrap();
        let opts = SimulateOptions {
            noise_model: model,
            ..base.clone()
        };
        let clean = SimulateOptions {
            noise: false,
            ..base
        };
        let noisy = simulate(&robot, &layout, &s.truth, &s.trajectory, &opts, seed).unwrap();
        let free = simulate(&robot, &layout, &s.truth, &s.trajectory, &clean, seed).unwrap();
        assert_eq!(noisy.imu_t, free.imu_t);
        let tau = s.truth[layout.offsets().tau];
        let mut js = JointState::default();
        let qdd2 = noisy
            .imu_t
            .iter()
            .map(|&t| {
                s.trajectory.state_at(t + tau, &mut js);
                js.qdd[..robot.dof()].iter().map(|a| a * a).sum()
            })
            .collect();
        let r = noisy
            .imu_z
            .iter()
            .zip(&free.imu_z)
            .map(|(a, b)| std::array::from_fn(|c| a[c] - b[c]))
            .collect();
        (r, qdd2)
    }

    /// The bias walk by Monte Carlo against the Brownian motion's own laws:
    /// over 400 seeds, the change from the first to the last of 300 s of
    /// 120 Hz samples has variance (scale·D)²·300/1500 and the changes over
    /// the two halves are uncorrelated (independent increments); the walk
    /// has zero mean over the session, and scale 0 adds nothing.
    #[test]
    fn the_bias_walk_has_brownian_statistics() {
        let t: Vec<f64> = (0..=36_000).map(|i| i as f64 / 120.0).collect();
        let (runs, scale) = (400, 20.0);
        let (mut var, mut cross, mut var_half) = ([0.0; 6], [0.0; 6], [0.0; 6]);
        for seed in 0..runs {
            let w = bias_walk(&t, scale, seed);
            let (a, m, b) = (w[0], w[18_000], w[36_000]);
            for c in 0..6 {
                var[c] += (b[c] - a[c]).powi(2) / runs as f64;
                cross[c] += (m[c] - a[c]) * (b[c] - m[c]) / runs as f64;
                var_half[c] += (m[c] - a[c]).powi(2) / runs as f64;
                let mean = w.iter().map(|v| v[c]).sum::<f64>() / w.len() as f64;
                assert!(mean.abs() < 1e-12 * PAPER_DRIFT[c] * scale);
            }
        }
        for c in 0..6 {
            let want = (scale * PAPER_DRIFT[c]).powi(2) * 300.0 / PAPER_DRIFT_TIME;
            // the sample variance of 400 χ²₁ draws: relative se √(2/400) ≈ 0.07
            assert!(
                (var[c] / want - 1.0).abs() < 4.0 * 0.071,
                "channel {c}: {} vs {want}",
                var[c]
            );
            assert!((var_half[c] / (want / 2.0) - 1.0).abs() < 4.0 * 0.071);
            // the product of two independent halves: se (want/2)/√400
            assert!(
                cross[c].abs() < 4.0 * want / 2.0 / 20.0,
                "channel {c}: {}",
                cross[c]
            );
        }
        let mut d = Measurements {
            imu_t: t[..100].to_vec(),
            imu_z: vec![[1.0; 6]; 100],
            ..Measurements::default()
        };
        add_bias_walk(&mut d, 0.0, 3);
        assert!(d.imu_z.iter().all(|z| z == &[1.0; 6]));
    }

    /// Each IMU its own noise (`imu_noise`, docs/model.md §9): IMU 0 white
    /// at σ_z, IMU 1's accelerometer AR(1) φ = 0.9 at 2σ_z. The noise
    /// (noisy minus noise-free samples) has, on 60 s at 120 Hz, IMU 0's
    /// accelerometer lag-1 autocorrelation within 0.05 of 0 and σ within
    /// 5 %, IMU 1's within 0.03 of 0.9 and σ within 12 % (AR(1): ~380
    /// effective samples), both gyroscopes white at σ_z.
    #[test]
    fn each_imu_is_simulated_with_its_own_noise() {
        let robot = Robot::aubo_i5();
        let sz = robot.sigma_z();
        let layout = ParamLayout::with_imus(&robot, 2);
        let sz1: [f64; 6] = std::array::from_fn(|c| sz[c] * if c < 3 { 2.0 } else { 1.0 });
        let mut opts = SimulateOptions::paper(&robot);
        opts.imu_noise = vec![
            NoiseModel::white(sz).unwrap(),
            NoiseModel::ar1(sz1, [Some(0.9), None], [0.0; 2]).unwrap(),
        ];
        let s = random_session_imus(&robot, 2, 60.0, 1.0, &opts, 21).unwrap();
        let clean = SimulateOptions {
            noise: false,
            ..opts.clone()
        };
        let free = simulate(&robot, &layout, &s.truth, &s.trajectory, &clean, 21).unwrap();
        for (j, (phi, sigma)) in [(0.0, sz), (0.9, sz1)].into_iter().enumerate() {
            let (noisy, free) = (s.data.imu(j), free.imu(j));
            assert_eq!(noisy.t, free.t);
            for c in 0..6 {
                let n: Vec<f64> = noisy
                    .z
                    .iter()
                    .zip(free.z)
                    .map(|(a, b)| a[c] - b[c])
                    .collect();
                let len = n.len() as f64;
                let var = n.iter().map(|v| v * v).sum::<f64>() / len;
                let rho = n.windows(2).map(|w| w[0] * w[1]).sum::<f64>() / (len - 1.0) / var;
                let ratio = var.sqrt() / sigma[c];
                let (want_rho, rho_tol, tol) = if c < 3 && phi > 0.0 {
                    (phi, 0.03, 0.12)
                } else {
                    (0.0, 0.05, 0.05)
                };
                assert!(
                    (rho - want_rho).abs() < rho_tol,
                    "IMU {j} ch {c}: ρ1 {rho:.3}"
                );
                assert!(
                    (ratio - 1.0).abs() < tol,
                    "IMU {j} ch {c}: σ ratio {ratio:.3}"
                );
            }
        }
    }

    #[test]
    fn white_noise_model_gives_the_same_samples_as_none() {
        let robot = Robot::aubo_i5();
        let layout = ParamLayout::new(&robot);
        let base = SimulateOptions::paper(&robot);
        let s = random_session(&robot, 20.0, 1.0, &base, 5).unwrap();
        let opts = SimulateOptions {
            noise_model: Some(NoiseModel::white(robot.sigma_z()).unwrap()),
            ..base
        };
        let d = simulate(&robot, &layout, &s.truth, &s.trajectory, &opts, 5).unwrap();
        assert_eq!(d.imu_t, s.data.imu_t);
        assert_eq!(d.joint_q, s.data.joint_q);
        for (a, b) in d.imu_z.iter().zip(&s.data.imu_z) {
            for c in 0..6 {
                assert_eq!(a[c].to_bits(), b[c].to_bits());
            }
        }
    }

    /// Bartlett's standard error of the sample autocovariance at lag h of
    /// N samples of a process of autocovariances `g` (known zero mean).
    fn bartlett_se(g: &[f64], h: usize, n: usize) -> f64 {
        let at = |j: i64| g.get(j.unsigned_abs() as usize).copied().unwrap_or(0.0);
        let l = g.len() as i64 - 1;
        let h = h as i64;
        let v: f64 = (-l..=l)
            .map(|j| at(j) * at(j) + at(j + h) * at(j - h))
            .sum();
        (v / n as f64).sqrt()
    }

    #[test]
    fn correlated_noise_has_the_model_autocovariance() {
        let sz = Robot::aubo_i5().sigma_z();
        let mut model = NoiseModel::white(sz).unwrap();
        model.imu[0].ar = ArNoise::new(vec![1.2, -0.5], sz[0]).unwrap();
        model.imu[3].ar = ArNoise::new(vec![0.9], sz[3]).unwrap();
        model.imu[5].ar = ArNoise::new(vec![0.5, 0.2, -0.3], sz[5]).unwrap();
        let (r, _) = noise_of(Some(model.clone()), 600.0, 11);
        let n = r.len();
        assert!(n > 70_000);
        for c in 0..6 {
            let g = model.imu[c].ar.autocovariance(400);
            for h in 0..=6 {
                let got: f64 = (0..n - h).map(|t| r[t][c] * r[t + h][c]).sum::<f64>() / n as f64;
                let se = bartlett_se(&g, h, n);
                assert!(
                    (got - g[h]).abs() < 4.0 * se,
                    "channel {c} lag {h}: {got} vs {} (se {se})",
                    g[h]
                );
            }
        }
        // Stationary from the first sample (no burn-in): over many short
        // segments, the first samples' covariances are the model's.
        let ar = ArNoise::new(vec![1.2, -0.5], 1.0).unwrap();
        let g = ar.autocovariance(2);
        let mut m = NoiseModel::white([1.0; 6]).unwrap();
        m.imu[0].ar = ar;
        let mut sampler = NoiseSampler::new(m);
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let reps = 40_000;
        let mut acc = [[0.0; 3]; 3];
        for _ in 0..reps {
            sampler.restart();
            let u: Vec<f64> = (0..3)
                .map(|_| {
                    sampler.next(
                        std::array::from_fn(|_| StandardNormal.sample(&mut rng)),
                        0.0,
                    )[0]
                })
                .collect();
            for i in 0..3 {
                for j in 0..3 {
                    acc[i][j] += u[i] * u[j] / reps as f64;
                }
            }
        }
        for i in 0..3_usize {
            for j in 0..3_usize {
                let want = g[i.abs_diff(j)];
                // Var of a product of two unit-variance normals ≤ 2.
                let se = (2.0 / reps as f64).sqrt();
                assert!(
                    (acc[i][j] - want).abs() < 4.0 * se,
                    "({i},{j}) {} vs {want}",
                    acc[i][j]
                );
            }
        }
    }

    #[test]
    fn noise_level_follows_the_motion() {
        let sz = Robot::aubo_i5().sigma_z();
        let (_, qdd2) = noise_of(None, 300.0, 17);
        let mean = qdd2.iter().sum::<f64>() / qdd2.len() as f64;
        let mut model = NoiseModel::white(sz).unwrap();
        // Channel 1 white with a motion gain, channel 4 AR(1) with one,
        // both three times σ² at the mean ‖q̈‖².
        model.imu[1] =
            ChannelNoise::new(model.imu[1].ar.clone(), 3.0 * sz[1] * sz[1] / mean).unwrap();
        let ar = ArNoise::new(vec![0.8], sz[4]).unwrap();
        model.imu[4] = ChannelNoise::new(ar, 3.0 * sz[4] * sz[4] / mean).unwrap();
        let (r, qdd2) = noise_of(Some(model.clone()), 300.0, 17);
        let mut order: Vec<usize> = (0..qdd2.len()).collect();
        order.sort_by(|&a, &b| qdd2[a].total_cmp(&qdd2[b]));
        let bins = 5;
        for c in [0, 1, 4] {
            let ch = &model.imu[c];
            let s2 = ch.ar.sigma().powi(2);
            let mut ratios = Vec::new();
            for b in 0..bins {
                let idx = &order[b * order.len() / bins..(b + 1) * order.len() / bins];
                let k = idx.len() as f64;
                let got = idx.iter().map(|&i| r[i][c] * r[i][c]).sum::<f64>() / k;
                let want = idx.iter().map(|&i| s2 + ch.motion * qdd2[i]).sum::<f64>() / k;
                // n_t/σ_t is unit normal; correlated samples inflate the
                // variance of the mean square by S(0)-like factor ≤ (1+φ²)/(1−φ²).
                let inflate = if c == 4 {
                    (1.0 + 0.64) / (1.0 - 0.64)
                } else {
                    1.0
                };
                let max_rel = idx
                    .iter()
                    .map(|&i| (s2 + ch.motion * qdd2[i]) / want)
                    .fold(0.0, f64::max);
                let se = (2.0 * inflate / k).sqrt() * max_rel;
                assert!(
                    (got / want - 1.0).abs() < 4.0 * se,
                    "channel {c} bin {b}: {got} vs {want} (rel se {se})"
                );
                ratios.push(got / s2);
            }
            if c != 0 {
                assert!(
                    ratios[bins - 1] > 3.0 * ratios[0],
                    "channel {c}: {ratios:?}"
                );
            }
        }
    }
}
