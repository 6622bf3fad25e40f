//! The catalogue of model extensions ("effects"): real, parametrised terms
//! the estimator can add to the measurement model of docs/model.md §4 when the
//! residuals show structure the baseline model does not explain.
//!
//! Every effect is linear in its parameters θ_e (to first order in the
//! effect, which is all a score test or a small-effect refit needs):
//!
//! ```text
//! z_i = h(x, q(t_i + τ)) + Σ_e  C_e(i) θ_e          C_e(i) = ∂z_i/∂θ_e  (6 × k_e)
//! ```
//!
//! so an effect is its Jacobian `C_e(i)`, built per IMU sample from a
//! [`SampleContext`]: the sample time, the joint state q(t_i+τ) (and its
//! derivatives), the baseline model and its analytic Jacobians (∂z/∂q,
//! ∂z/∂q̇, ∂z/∂q̈ and ∂z/∂τ = dz/dt), and the IMU-frame ω, ω̇ and s. Effects
//! that act through the joint angles (encoder scale, elasticity) or the
//! clock (clock drift, sensor delay) use the chain rule through those analytic
//! Jacobians; the cross-derivatives ∂C_e/∂x are neglected (the refit
//! minimises the exact cost; see the tests for the agreement with an
//! exact-injection simulation).
//!
//! Besides the linear term, each effect has an *exact* form used by the
//! simulator ([`Effect::exact`]): the IMU sample computed from the effect's
//! physics (a warped clock, scaled or deflected joint angles, …); by default
//! the linear term. The tests check the Jacobian against finite
//! differences of this exact form.
//!
//! # Adding an effect
//!
//! Write one module implementing [`Effect`] and add it to [`catalogue`] (the
//! one registration point). Name it in snake case; the name is what the CLI
//! (`--effects`, `--effect NAME=MAGNITUDE`) and `diagnosis.json` use.

pub mod bias_drift;
pub mod clock_drift;
pub mod encoder_scale;
pub mod g_sensitivity;
pub mod joint_elasticity;
pub mod mass;
pub mod resonance;
pub mod sensor_delay;
pub mod size_effect;
pub mod temperature_bias;

use std::cell::OnceCell;
use std::sync::Arc;

use crate::geom::{cross, M3, V3};
use crate::{JointState, MeasurementJacobians, MeasurementModel, ParamLayout, Spline};

pub use mass::MassModel;

/// One parameter of an effect.
#[derive(Debug, Clone, PartialEq)]
pub struct EffectParam {
    /// Name, `<effect>.<component>` (e.g. `clock_drift.ppm`).
    pub name: String,
    /// SI unit of the value in θ_e.
    pub unit: &'static str,
    /// Display unit and the factor from SI to it.
    pub display: (&'static str, f64),
    /// σ of the (broad, zero-mean) prior used in refits, SI.
    pub prior_sigma: f64,
}

/// A fixed value an effect's parameters are relative to (T_ref of
/// `temperature_bias`, the reference time of `clock_drift`, …): written
/// beside θ_e (docs/model.md §8.4) so that a correction can be applied
/// later without the session.
#[derive(Debug, Clone, PartialEq)]
pub struct EffectConstant {
    /// Name, `<effect>.<constant>` (e.g. `temperature_bias.t_ref`).
    pub name: String,
    /// Unit of the value.
    pub unit: &'static str,
    /// The value.
    pub value: f64,
}

/// Everything an effect may need at one IMU sample.
pub struct SampleContext<'a> {
    /// IMU sample time t_i on the session clock, s.
    pub t: f64,
    /// q(t_i + τ) and its derivatives (the encoder readings' trajectory).
    pub js: &'a JointState,
    /// The baseline model at the current x.
    pub model: &'a MeasurementModel,
    /// Baseline z and analytic Jacobians at `js` (`dz_dx[tau]` is dz/dt).
    pub jac: &'a MeasurementJacobians,
    /// Index of τ in x.
    pub tau_index: usize,
    /// ω and s at the sample (computed on first use).
    motion: OnceCell<(V3, V3)>,
    inertial: OnceCell<Inertial>,
}

/// IMU-frame angular rate ω, its derivative ω̇ and the specific force s.
#[derive(Debug, Clone, Copy)]
pub struct Inertial {
    /// ω, rad/s.
    pub omega: V3,
    /// ω̇, rad/s² (central difference over ±1 ms of the joint state's
    /// Taylor expansion; exact to O(h²) for the cubic trajectory).
    pub omega_dot: V3,
    /// s, m/s².
    pub s: V3,
}

/// What an IMU-side effect sees at one sample: the IMU's own quantities,
/// which a joint-angle session ([`SampleContext`]) and a pose session
/// ([`crate::pose_measurement::inertial::PoseImuSample`]) both give
/// (docs/model.md §7.9). An effect whose columns need only these
/// implements [`Effect::imu_columns`]; the joint-side ones (acting through
/// the joint angles or the links) cannot.
pub trait ImuContext {
    /// IMU sample time t_i on the session clock, s.
    fn t(&self) -> f64;
    /// ω and s in the IMU frame.
    fn omega_and_force(&self) -> (V3, V3);
    /// ω, ω̇ and s in the IMU frame.
    fn inertial(&self) -> Inertial;
    /// dz/dt along the trajectory (∂z/∂τ).
    fn dz_dt(&self) -> [f64; 6];
    /// The accelerometer's M_a = K_a Γ_a R_a (paper eq. (6)).
    fn accel_matrix(&self) -> M3;
}

/// What the exact (simulator) form of an IMU-side effect sees: the sample,
/// τ, the baseline z at any trajectory time and the IMU's quantities at
/// t_i + τ.
pub struct ImuExactContext<'a> {
    /// IMU sample time t_i on the session clock, s.
    pub t: f64,
    /// τ, s.
    pub tau: f64,
    /// Baseline z at a trajectory time (session time + τ).
    pub z_at: &'a dyn Fn(f64) -> [f64; 6],
    /// The IMU's quantities at t_i + τ.
    pub imu: &'a dyn ImuContext,
}

/// Step of the central differences in time, s.
pub(crate) const TIME_STEP: f64 = 1e-3;

/// The joint state `h` seconds later by the Taylor expansion of
/// (q, q̇, q̈, q⃛) (exact inside a span of a cubic trajectory).
pub fn shifted(js: &JointState, h: f64) -> JointState {
    let mut o = *js;
    for j in 0..js.q.len() {
        let (q, qd, qdd, qddd) = (js.q[j], js.qd[j], js.qdd[j], js.qddd[j]);
        o.q[j] = q + h * qd + h * h / 2.0 * qdd + h * h * h / 6.0 * qddd;
        o.qd[j] = qd + h * qdd + h * h / 2.0 * qddd;
        o.qdd[j] = qdd + h * qddd;
    }
    o
}

impl<'a> SampleContext<'a> {
    /// The context of one sample.
    pub fn new(
        t: f64,
        js: &'a JointState,
        model: &'a MeasurementModel,
        jac: &'a MeasurementJacobians,
        layout: &ParamLayout,
    ) -> Self {
        Self {
            t,
            js,
            model,
            jac,
            tau_index: layout.offsets().tau,
            motion: OnceCell::new(),
            inertial: OnceCell::new(),
        }
    }

    /// ω and s in the IMU frame (computed once, on first use): what
    /// [`Self::inertial`] has without ω̇ and its two further evaluations of
    /// the model.
    pub fn omega_and_force(&self) -> (V3, V3) {
        *self.motion.get_or_init(|| {
            let (_, omega, s) = self.model.inertial(self.js);
            (omega, s)
        })
    }

    /// ω, ω̇, s in the IMU frame (computed once, on first use).
    pub fn inertial(&self) -> &Inertial {
        self.inertial.get_or_init(|| {
            let (omega, s) = self.omega_and_force();
            let h = TIME_STEP;
            let (_, wp, _) = self.model.inertial(&shifted(self.js, h));
            let (_, wm, _) = self.model.inertial(&shifted(self.js, -h));
            let omega_dot = std::array::from_fn(|k| (wp[k] - wm[k]) / (2.0 * h));
            Inertial {
                omega,
                omega_dot,
                s,
            }
        })
    }

    /// dz/dt along the trajectory (the τ column of the analytic Jacobian).
    pub fn dz_dt(&self) -> [f64; 6] {
        self.jac.dz_dx[self.tau_index]
    }

    /// ∂z/∂θ for a perturbation of the joint state δq, δq̇, δq̈ (n joints):
    /// Σ_j ∂z/∂q_j δq_j + ∂z/∂q̇_j δq̇_j + ∂z/∂q̈_j δq̈_j.
    pub fn through_joints(&self, j: usize, dq: f64, dqd: f64, dqdd: f64) -> [f64; 6] {
        let jac = self.jac;
        std::array::from_fn(|c| {
            jac.dz_dq[j][c] * dq + jac.dz_dqd[j][c] * dqd + jac.dz_dqdd[j][c] * dqdd
        })
    }
}

impl ImuContext for SampleContext<'_> {
    fn t(&self) -> f64 {
        self.t
    }
    fn omega_and_force(&self) -> (V3, V3) {
        SampleContext::omega_and_force(self)
    }
    fn inertial(&self) -> Inertial {
        *SampleContext::inertial(self)
    }
    fn dz_dt(&self) -> [f64; 6] {
        SampleContext::dz_dt(self)
    }
    fn accel_matrix(&self) -> M3 {
        self.model.params().accel.matrix()
    }
}

/// What the exact (simulator) form of an effect sees: the true trajectory at
/// any time and the baseline model.
pub struct ExactContext<'a> {
    /// IMU sample time t_i on the session clock, s.
    pub t: f64,
    /// τ, s.
    pub tau: f64,
    /// The baseline model at the true x.
    pub model: &'a MeasurementModel,
    /// The joint trajectory (encoder readings) at any session time.
    pub trajectory: &'a dyn Fn(f64) -> JointState,
}

impl ExactContext<'_> {
    /// Baseline z at t_i (no effect).
    pub fn baseline(&self) -> [f64; 6] {
        self.model.predict(&(self.trajectory)(self.t + self.tau))
    }
}

/// Session-level facts some effects need (set once per session).
#[derive(Debug, Clone)]
pub struct SessionSpan {
    /// First and last IMU sample time, s.
    pub t0: f64,
    /// Last IMU sample time, s.
    pub t1: f64,
}

impl SessionSpan {
    /// Middle of the span, s (reference time of drifting effects).
    pub fn mid(&self) -> f64 {
        0.5 * (self.t0 + self.t1)
    }
    /// Time normalised to [−1, 1] over the span.
    pub fn unit(&self, t: f64) -> f64 {
        let h = 0.5 * (self.t1 - self.t0);
        if h > 0.0 {
            (t - self.mid()) / h
        } else {
            0.0
        }
    }
}

/// A candidate model extension (see the module doc).
pub trait Effect: Send + Sync {
    /// Snake-case name (CLI and JSON).
    fn name(&self) -> &'static str;
    /// One-line description with the physics.
    fn description(&self) -> &'static str;
    /// The parameters θ_e, in order.
    fn params(&self) -> Vec<EffectParam>;
    /// ∂z/∂θ_e at one sample: one 6-column per parameter into `cols`.
    fn columns(&self, ctx: &SampleContext<'_>, cols: &mut [[f64; 6]]);
    /// [`Self::columns`] from the IMU's own quantities alone ([`ImuContext`]),
    /// for an effect that needs no joint state; `false` (the default, `cols`
    /// untouched) for one that does: it does not apply to a pose session.
    fn imu_columns(&self, _ctx: &dyn ImuContext, _cols: &mut [[f64; 6]]) -> bool {
        false
    }
    /// The exact (simulator) z of an IMU-side effect at θ_e in a session
    /// whose baseline z is `ctx.z_at` (a pose session's); `None` for a
    /// joint-side effect. Default: baseline plus the linear term.
    fn imu_exact(&self, ctx: &ImuExactContext<'_>, theta: &[f64]) -> Option<[f64; 6]> {
        let mut cols = vec![[0.0; 6]; theta.len()];
        if !self.imu_columns(ctx.imu, &mut cols) {
            return None;
        }
        let mut z = (ctx.z_at)(ctx.t + ctx.tau);
        for (col, th) in cols.iter().zip(theta) {
            for c in 0..6 {
                z[c] += col[c] * th;
            }
        }
        Some(z)
    }
    /// The exact (simulator) z with the effect at θ_e. Default: baseline
    /// plus the linear term (exact for effects additive in z).
    fn exact(&self, ctx: &ExactContext<'_>, theta: &[f64], layout: &ParamLayout) -> [f64; 6] {
        let js = (ctx.trajectory)(ctx.t + ctx.tau);
        let mut jac = MeasurementJacobians::new(layout.len());
        ctx.model.jacobians(&js, &mut jac);
        let sc = SampleContext::new(ctx.t, &js, ctx.model, &jac, layout);
        let mut cols = vec![[0.0; 6]; theta.len()];
        self.columns(&sc, &mut cols);
        let mut z = jac.z;
        for (col, th) in cols.iter().zip(theta) {
            for c in 0..6 {
                z[c] += col[c] * th;
            }
        }
        z
    }
    /// The fixed values θ_e is relative to (default: none).
    fn constants(&self) -> Vec<EffectConstant> {
        Vec::new()
    }
    /// The unit of the scalar magnitude of `simulate --effect NAME=M`.
    fn magnitude_unit(&self) -> &'static str;
    /// θ_e injected by `simulate --effect NAME=M` (a documented fixed pattern
    /// scaled by M).
    fn injection(&self, magnitude: f64) -> Vec<f64>;
}

/// What the catalogue's effects are built from.
#[derive(Debug, Clone)]
pub struct CatalogueSetup {
    /// The IMU time span of the session.
    pub span: SessionSpan,
    /// The mass model for joint elasticity.
    pub mass: MassModel,
    /// Gravity magnitude g0, m/s².
    pub g0: f64,
    /// The resonance's natural frequency and damping.
    pub mode: resonance::Mode,
    /// The mode's response to the recorded joint trajectory (`None`: no
    /// trajectory could be fitted; `resonance` is then unavailable),
    /// integrated on its first use ([`resonance::ModeResponse::prepare`]).
    pub mode_response: Option<Arc<resonance::ModeResponse>>,
    /// Segments of `bias_drift`'s bias spline (its time resolution;
    /// [`bias_drift::DEFAULT_SEGMENTS`] unless set, diagnose chooses it
    /// from the data).
    pub bias_drift_segments: usize,
    /// The smoothed IMU temperature (`None`: not recorded or constant;
    /// `temperature_bias` is then unavailable).
    pub temperature: Option<Arc<temperature_bias::TemperatureTrack>>,
    /// Number of IMUs K of the session (docs/model.md §9; 1 unless set).
    pub n_imus: usize,
    /// The smoothed temperature of IMU j ≥ 1 at `j − 1` (IMU 0's is
    /// `temperature`); `temperature_bias` of IMU j uses its own.
    pub imu_temperatures: Vec<Option<Arc<temperature_bias::TemperatureTrack>>>,
}

/// The effects of one IMU's chip or mount (its clock, its sensors'
/// cross-sensitivities and biases, its lever arms): with several IMUs each
/// has its own parameters, named `imu<j>/<effect>` for j ≥ 1 (docs/model.md
/// §9). The others are the robot's (joints, links, masses) and shared.
pub const PER_SENSOR: [&str; 6] = [
    "g_sensitivity",
    "size_effect",
    "clock_drift",
    "sensor_delay",
    "bias_drift",
    "temperature_bias",
];

/// Whether effect `name` (a catalogue name, no prefix) is per sensor ([`PER_SENSOR`]).
pub fn is_per_sensor(name: &str) -> bool {
    PER_SENSOR.contains(&name)
}

/// A candidate's label split into its IMU and effect name: `imu<j>/<effect>`
/// (j ≥ 1) → `(Some(j), effect)`; a plain name → `(None, name)`. `None`
/// when the prefix is malformed (`imu0/`, `imux/`).
pub fn split_label(label: &str) -> Option<(Option<usize>, &str)> {
    match label.split_once('/') {
        None => Some((None, label)),
        Some((imu, name)) => {
            let j: usize = imu.strip_prefix("imu")?.parse().ok()?;
            (j >= 1 && !imu[3..].starts_with('0') && !imu[3..].starts_with('+'))
                .then_some((Some(j), name))
        }
    }
}

/// The label of effect `name` on IMU `imu` (`None`: shared, or IMU 0):
/// `imu<j>/<name>` for j ≥ 1, else `name`.
pub fn label(imu: Option<usize>, name: &str) -> String {
    match imu {
        Some(j) if j >= 1 => format!("imu{j}/{name}"),
        _ => name.to_string(),
    }
}

impl CatalogueSetup {
    /// The setup for a session over `span` whose recorded joints follow
    /// `joints` (a spline fitted to them), with the default mode.
    pub fn new(span: SessionSpan, mass: MassModel, g0: f64, joints: Option<&Spline>) -> Self {
        let mode = resonance::Mode::default();
        let mut s = Self {
            span,
            mass,
            g0,
            mode,
            mode_response: None,
            bias_drift_segments: bias_drift::DEFAULT_SEGMENTS,
            temperature: None,
            n_imus: 1,
            imu_temperatures: Vec::new(),
        };
        s.set_joints(mode, joints);
        s
    }
    /// Smooth the IMU temperature readings `temp` (°C) at the IMU times `t`
    /// into the track of `temperature_bias` (none when they do not vary,
    /// [`temperature_bias::TemperatureTrack::from_samples`]).
    pub fn set_temperature(&mut self, t: &[f64], temp: &[f64]) {
        self.temperature = temperature_bias::TemperatureTrack::from_samples(t, temp).map(Arc::new);
    }
    /// Smooth IMU `j`'s temperature readings into its track (j = 0:
    /// [`Self::set_temperature`]).
    pub fn set_imu_temperature(&mut self, j: usize, t: &[f64], temp: &[f64]) {
        if j == 0 {
            return self.set_temperature(t, temp);
        }
        if self.imu_temperatures.len() < j {
            self.imu_temperatures.resize(j, None);
        }
        self.imu_temperatures[j - 1] =
            temperature_bias::TemperatureTrack::from_samples(t, temp).map(Arc::new);
    }
    /// The set-up IMU `j`'s per-sensor effects are built from (its own
    /// temperature; `self` for IMU 0).
    pub fn imu_setup(&self, j: usize) -> CatalogueSetup {
        let mut s = self.clone();
        if j >= 1 {
            s.temperature = self.imu_temperatures.get(j - 1).cloned().flatten();
        }
        s
    }
    /// Every candidate of the session: each per-sensor effect once per IMU
    /// (where that IMU's catalogue has it), each shared effect once, as
    /// labels ([`label`]): IMU 0's catalogue in its order (the one-IMU
    /// candidates), then IMU 1's per-sensor effects, ….
    pub fn candidates(&self) -> Vec<String> {
        let mut out: Vec<String> = catalogue(self)
            .iter()
            .map(|e| e.name().to_string())
            .collect();
        for j in 1..self.n_imus {
            let setup = self.imu_setup(j);
            for e in catalogue(&setup) {
                if is_per_sensor(e.name()) {
                    out.push(label(Some(j), e.name()));
                }
            }
        }
        out
    }
    /// Set the resonance mode and integrate its response to `joints`.
    pub fn set_joints(&mut self, mode: resonance::Mode, joints: Option<&Spline>) {
        self.mode = mode;
        self.mode_response = joints.map(|s| Arc::new(resonance::ModeResponse::of_spline(mode, s)));
    }
    /// The resolution of effect `name` in this set-up (`None`: it has none).
    pub fn resolution(&self, name: &str) -> Option<usize> {
        let name = split_label(name).map_or(name, |(_, n)| n);
        (name == "bias_drift").then_some(self.bias_drift_segments)
    }
    /// Set the resolution of effect `name`.
    pub fn set_resolution(&mut self, name: &str, m: usize) -> Result<(), EffectSpecError> {
        let name = split_label(name).map_or(name, |(_, n)| n);
        if !NAMES.contains(&name) {
            return Err(UnknownEffect(name.to_string()).into());
        }
        if self.resolution(name).is_none() {
            return Err(EffectSpecError::NoResolution(name.to_string()));
        }
        if !(1..=bias_drift::MAX_SEGMENTS).contains(&m) {
            return Err(EffectSpecError::Resolution {
                name: name.to_string(),
                got: m.to_string(),
            });
        }
        self.bias_drift_segments = m;
        Ok(())
    }
    /// Apply an effect spec `NAME` or `NAME:M` (M the resolution of an
    /// effect that has one, e.g. `bias_drift:8`; `NAME` a label, e.g.
    /// `imu1/bias_drift:8`, the resolution then shared by every IMU's);
    /// the effect's label.
    pub fn apply_spec(&mut self, spec: &str) -> Result<String, EffectSpecError> {
        let (label, m) = match spec.split_once(':') {
            Some((n, m)) => (n.trim(), Some(m.trim())),
            None => (spec.trim(), None),
        };
        self.check_label(label)?;
        let name = split_label(label).map_or(label, |(_, n)| n);
        let name = NAMES
            .iter()
            .copied()
            .find(|n| *n == name)
            .ok_or_else(|| UnknownEffect(label.to_string()))?;
        if let Some(m) = m {
            let bad = || EffectSpecError::Resolution {
                name: name.to_string(),
                got: m.to_string(),
            };
            let v: usize = m.parse().map_err(|_| bad())?;
            self.set_resolution(name, v).map_err(|e| match e {
                EffectSpecError::Resolution { .. } => bad(),
                e => e,
            })?;
        }
        Ok(label.to_string())
    }
    /// Whether `label` names an effect this session can have: a catalogue
    /// name, an `imu<j>/` prefix only on a per-sensor effect and j < K.
    pub fn check_label(&self, label: &str) -> Result<(), UnknownEffect> {
        let unknown = || UnknownEffect(label.to_string());
        let (imu, name) = split_label(label).ok_or_else(unknown)?;
        if !NAMES.contains(&name) {
            return Err(unknown());
        }
        match imu {
            Some(j) if !is_per_sensor(name) || j >= self.n_imus => Err(unknown()),
            _ => Ok(()),
        }
    }
    /// The spec of effect `name` in this set-up: `NAME:M` for an effect
    /// with a resolution, else `NAME` ([`Self::apply_spec`] reads it back).
    pub fn spec(&self, name: &str) -> String {
        match self.resolution(name) {
            Some(m) => format!("{name}:{m}"),
            None => name.to_string(),
        }
    }
}

/// A bad effect spec (`NAME` or `NAME:M`).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EffectSpecError {
    /// The name is not in the catalogue.
    #[error(transparent)]
    Unknown(#[from] UnknownEffect),
    /// `NAME:M` for an effect without a resolution.
    #[error("effect `{0}` has no resolution to set (only bias_drift:M takes one)")]
    NoResolution(String),
    /// M is not a whole number in range.
    #[error("effect `{name}`: resolution `{got}` is not a whole number of segments from 1 to {max}", max = bias_drift::MAX_SEGMENTS)]
    Resolution {
        /// The effect.
        name: String,
        /// What was given.
        got: String,
    },
}

/// The catalogue: every known effect (the one registration point).
pub fn catalogue(setup: &CatalogueSetup) -> Vec<Box<dyn Effect>> {
    let mut all: Vec<Box<dyn Effect>> = vec![
        Box::new(g_sensitivity::GSensitivity),
        Box::new(size_effect::SizeEffect),
        Box::new(clock_drift::ClockDrift::new(setup.span.clone())),
        Box::new(sensor_delay::SensorDelay),
        Box::new(bias_drift::BiasDrift::new(
            setup.span.clone(),
            setup.bias_drift_segments,
        )),
        Box::new(joint_elasticity::JointElasticity::new(
            setup.mass.clone(),
            setup.g0,
        )),
        Box::new(encoder_scale::EncoderScale::new(setup.mass.dof())),
    ];
    if let Some(response) = &setup.mode_response {
        all.push(Box::new(resonance::Resonance::new(
            setup.mode,
            setup.mass.dof(),
            response.clone(),
            (setup.span.t0, setup.span.t1),
        )));
    }
    if let Some(track) = &setup.temperature {
        all.push(Box::new(temperature_bias::TemperatureBias::new(
            track.clone(),
        )));
    }
    all
}

/// Names of the catalogue's effects, in order.
pub const NAMES: [&str; 9] = [
    "g_sensitivity",
    "size_effect",
    "clock_drift",
    "sensor_delay",
    "bias_drift",
    "joint_elasticity",
    "encoder_scale",
    "resonance",
    "temperature_bias",
];

/// An effect name that is not in the catalogue of a session: unknown, or
/// known but not available there (its message says what it needs).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}", unknown_message(.0))]
pub struct UnknownEffect(pub String);

/// What a known effect that a catalogue can lack needs from the session.
fn requirement(name: &str) -> Option<&'static str> {
    match name {
        "resonance" => Some("a recorded joint trajectory that can be fitted"),
        "temperature_bias" => Some(temperature_bias::REQUIRES),
        _ => None,
    }
}

fn unknown_message(name: &str) -> String {
    if let Some((Some(j), base)) = split_label(name) {
        if NAMES.contains(&base) {
            return if let Some(needs) = requirement(base).filter(|_| is_per_sensor(base)) {
                format!("effect `{name}` is not available for this session: it needs IMU {j} with {needs}")
            } else if is_per_sensor(base) {
                format!("effect `{name}`: this session has no IMU {j}")
            } else {
                format!(
                    "effect `{name}`: {base} is the robot's, shared by every IMU; name it without `imu{j}/`"
                )
            };
        }
    } else if split_label(name).is_none() {
        return format!(
            "effect `{name}`: `imu<j>/` takes an IMU j ≥ 1 (IMU 0's effects have no prefix)"
        );
    }
    match requirement(name) {
        Some(needs) => {
            format!("effect `{name}` is not available for this session: it needs {needs}")
        }
        None => format!("unknown effect `{name}` (known: {})", NAMES.join(", ")),
    }
}

/// The effect labelled `name` (a catalogue name, or `imu<j>/<name>` for IMU
/// j's per-sensor effect, built from its [`CatalogueSetup::imu_setup`]).
pub fn by_name(setup: &CatalogueSetup, name: &str) -> Result<Box<dyn Effect>, UnknownEffect> {
    Ok(by_label(setup, name)?.0)
}

/// [`by_name`] with the effect's owner: `Some(j)` for a per-sensor effect
/// of IMU j (a plain name: IMU 0), `None` for a shared one.
pub fn by_label(
    setup: &CatalogueSetup,
    name: &str,
) -> Result<(Box<dyn Effect>, Option<usize>), UnknownEffect> {
    setup.check_label(name)?;
    let (imu, base) = split_label(name).ok_or_else(|| UnknownEffect(name.to_string()))?;
    let owner = is_per_sensor(base).then_some(imu.unwrap_or(0));
    let own = setup.imu_setup(owner.unwrap_or(0));
    catalogue(&own)
        .into_iter()
        .find(|e| e.name() == base)
        .map(|e| (e, owner))
        .ok_or_else(|| UnknownEffect(name.to_string()))
}

/// Several effects stacked: θ_E = [θ_e1, θ_e2, …]. The empty set is the
/// baseline model ([`EffectSet::none`]).
#[derive(Default)]
pub struct EffectSet {
    effects: Vec<Box<dyn Effect>>,
    offsets: Vec<usize>,
    params: Vec<EffectParam>,
    /// Per effect: the IMU whose rows it enters (`None`: every IMU's).
    owners: Vec<Option<usize>>,
    /// Per effect: its label ([`label`]).
    labels: Vec<String>,
}

impl EffectSet {
    /// No effect.
    pub const fn new() -> Self {
        Self {
            effects: Vec::new(),
            offsets: Vec::new(),
            params: Vec::new(),
            owners: Vec::new(),
            labels: Vec::new(),
        }
    }
    /// The empty set, for problems of the baseline model alone.
    pub fn none() -> &'static EffectSet {
        static NONE: EffectSet = EffectSet::new();
        &NONE
    }
    /// Append an effect that enters every IMU's rows (one IMU, or a
    /// shared effect).
    pub fn push(&mut self, e: Box<dyn Effect>) {
        self.push_on(e, None);
    }
    /// Append an effect entering only IMU `imu`'s rows (`None`: every
    /// IMU's, [`Self::push`]); for IMU j ≥ 1 its label and parameter names
    /// take the prefix `imu<j>/` (docs/model.md §9).
    pub fn push_on(&mut self, e: Box<dyn Effect>, imu: Option<usize>) {
        self.offsets.push(self.params.len());
        let prefix = label(imu, "");
        self.params.extend(e.params().into_iter().map(|mut p| {
            p.name = format!("{prefix}{}", p.name);
            p
        }));
        self.labels.push(label(imu, e.name()));
        self.owners.push(imu);
        self.effects.push(e);
    }
    /// Per effect, the IMU whose rows it enters (`None`: every IMU's).
    pub fn owners(&self) -> &[Option<usize>] {
        &self.owners
    }
    /// θ_E indices of the parameters IMU `j`'s rows depend on, in θ_E
    /// order: the map of its local effect columns ([`Self::columns_for`])
    /// into θ_E, as [`ParamLayout::imu_map`] is for x. The identity when
    /// every effect enters every IMU's rows.
    pub fn imu_map(&self, j: usize) -> Vec<usize> {
        let mut out = Vec::new();
        for (e, owner) in self.owners.iter().enumerate() {
            if owner.is_none_or(|o| o == j) {
                out.extend(self.range_of(e));
            }
        }
        out
    }
    /// θ_E range of effect number `e`.
    fn range_of(&self, e: usize) -> std::ops::Range<usize> {
        let end = self
            .offsets
            .get(e + 1)
            .copied()
            .unwrap_or(self.params.len());
        self.offsets[e]..end
    }
    /// Total number of parameters.
    pub fn len(&self) -> usize {
        self.params.len()
    }
    /// No parameter at all.
    pub fn is_empty(&self) -> bool {
        self.params.is_empty()
    }
    /// All parameters, in θ_E order.
    pub fn params(&self) -> &[EffectParam] {
        &self.params
    }
    /// The effects with the offset of their parameters in θ_E.
    pub fn effects(&self) -> impl Iterator<Item = (usize, &dyn Effect)> {
        self.offsets
            .iter()
            .copied()
            .zip(self.effects.iter().map(|e| e.as_ref()))
    }
    /// Every effect's [`Effect::constants`], in effect order.
    pub fn constants(&self) -> Vec<EffectConstant> {
        self.effects
            .iter()
            .zip(&self.owners)
            .flat_map(|(e, &imu)| {
                e.constants().into_iter().map(move |mut c| {
                    c.name = label(imu, &c.name);
                    c
                })
            })
            .collect()
    }
    /// Labels of the effects (`imu<j>/<name>` for IMU j ≥ 1's, [`label`]).
    pub fn names(&self) -> Vec<String> {
        self.labels.clone()
    }
    /// All columns ∂z/∂θ_E at one sample (`cols.len() == self.len()`).
    pub fn columns(&self, ctx: &SampleContext<'_>, cols: &mut [[f64; 6]]) {
        for (i, e) in self.effects.iter().enumerate() {
            self.columns_of(e.as_ref(), ctx, &mut cols[self.range_of(i)]);
        }
    }
    /// IMU `j`'s columns ∂z/∂θ_E at one of its samples, only for the
    /// parameters of [`Self::imu_map`]`(j)` (`cols.len()` its length).
    pub fn columns_for(&self, j: usize, ctx: &SampleContext<'_>, cols: &mut [[f64; 6]]) {
        let mut at = 0;
        for (e, owner) in self.owners.iter().enumerate() {
            if owner.is_none_or(|o| o == j) {
                let k = self.range_of(e).len();
                self.columns_of(self.effects[e].as_ref(), ctx, &mut cols[at..at + k]);
                at += k;
            }
        }
    }
    fn columns_of(&self, e: &dyn Effect, ctx: &SampleContext<'_>, cols: &mut [[f64; 6]]) {
        for c in cols.iter_mut() {
            *c = [0.0; 6];
        }
        e.columns(ctx, cols);
    }
}

/// [ω̇]× r + ω × (ω × r): the acceleration of a point at r (IMU frame)
/// relative to the IMU origin, in the IMU frame.
pub(crate) fn lever_acceleration(inertial: &Inertial, r: V3) -> V3 {
    let a = cross(inertial.omega_dot, r);
    let b = cross(inertial.omega, cross(inertial.omega, r));
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// The trajectory closure of a simulator: q(t) of the spline inside its
/// span, at rest at the end poses outside ([`Spline::state_at`](crate::Spline::state_at)).
pub fn trajectory_fn(spline: &Spline) -> impl Fn(f64) -> JointState + '_ {
    move |t| {
        let mut js = JointState::default();
        spline.state_at(t, &mut js);
        js
    }
}

#[cfg(test)]
mod tests;
