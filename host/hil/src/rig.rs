//! The hidden-truth rig: a simulated AUBO i5 and a simulated IMU board on
//! its flange, sharing one true motion.
//!
//! [`SimRig::spawn`] starts a [`SimAubo`] controller on loopback TCP (with
//! the robot's joint noise Σ_q as encoder noise and a tracking lag) and a
//! [`SimDevice`] (the real firmware core over a register-level BNO055 on a
//! pseudo-terminal, with a clock offset and drift) whose readings come from a
//! [`ModelSource`] at the hidden truth x*. A recorder talks to them exactly
//! as to hardware: `--imu` [`SimRig::imu_port`], `--robot`
//! [`SimRig::robot_spec`].
//!
//! Realism switches, all off by default (the ideal twin): the chip model
//! ([`SimRigConfig::chip`]: the register-level BNO055 in datasheet mode
//! filters and holds at its internal rates, on a clock
//! [`SimRigConfig::chip_clock_error_ppm`] off the arm's), IMU noise correlated in time
//! and stronger with motion ([`SimRigConfig::imu_noise`], docs/model.md
//! §4.6; [`SimRigConfig::with_vibration_noise`] builds issue 14's
//! accelerometer model), and a bias and temperature warm-up
//! ([`SimRigConfig::warm_up`]), and the IMU signal from an independent
//! chain with joint elasticity and a structural mode
//! ([`SimRigConfig::arm_physics`], [`crate::arm_physics`]).

use std::net::SocketAddr;

use rand::SeedableRng;
use robimu_hil_sim::aubo::{JointLimits, SimAubo, SimAuboConfig, SimAuboError, TrueMotion, JOINTS};
use robimu_hil_sim::device::{SecondSensor, SimDevice, SimDeviceConfig, SimDeviceError};
use robimu_hil_sim::ur::{SimUr, SimUrConfig, SimUrError};

pub use robimu_bno055_sim::ChipModel;

use super::arm_physics::StructuralMode;
pub use super::arm_physics::{ArmEffects, Elasticity};
use super::arm_physics::{ArmPhysics, ArmPhysicsError, UrdfArm};
pub use super::physics::WarmUp;
use super::physics::{vibration_noise, ModelSource};
use robimu_model::noise::{NoiseModel, NoiseModelError};
use robimu_model::params::draw_truth;
use robimu_model::{MeasurementModel, ModelError, ParamLayout, Robot};
use robimu_session::Truth;

/// Why the rig could not be started.
#[derive(Debug, thiserror::Error)]
pub enum RigError {
    /// The rig simulates a 6-joint arm.
    #[error("the simulated rig drives a {JOINTS}-joint arm; robot {name} has {dof} joints")]
    Joints {
        /// Robot name.
        name: String,
        /// Its joint count.
        dof: usize,
    },
    /// The truth is not a valid parameter vector.
    #[error("bad hidden truth: {0}")]
    Model(#[from] ModelError),
    /// The simulated controller did not start.
    #[error("cannot start the simulated robot controller: {0}")]
    Robot(#[from] SimAuboError),
    /// The simulated UR controller did not start.
    #[error("cannot start the simulated UR controller: {0}")]
    Ur(#[from] SimUrError),
    /// The simulated IMU board did not start.
    #[error("cannot start the simulated IMU board: {0}")]
    Device(#[from] SimDeviceError),
    /// The arm's hidden effects are not valid.
    #[error("bad simulated arm: {0}")]
    Arm(#[from] ArmPhysicsError),
    /// The IMU noise model asked for is not valid.
    #[error("bad simulated IMU noise: {0}")]
    Noise(#[from] NoiseModelError),
}

/// What to simulate.
#[derive(Clone, Debug)]
pub struct SimRigConfig {
    /// The robot and its IMU mount (its description's priors and noise).
    pub robot: Robot,
    /// The hidden truth x* ([`ParamLayout::new`]`(&robot)` order); τ is
    /// forced to 0, as the physics reads the arm at the stamping instant.
    pub truth: Vec<f64>,
    /// Joint angles at power-up, rad.
    pub initial: [f64; JOINTS],
    /// Seed of the IMU noise, the encoder noise and the injected faults.
    pub seed: u64,
    /// Device clock at start, µs.
    pub clock_offset_us: u64,
    /// Device clock rate error, ppm.
    pub clock_drift_ppm: f64,
    /// The controller's first-order tracking lag, s.
    pub tracking_lag_s: f64,
    /// How the simulated BNO055 fills its data registers (default
    /// [`ChipModel::Ideal`]: the model's reading at each firmware read).
    pub chip: ChipModel,
    /// The datasheet chip's internal clock rate error against the arm's
    /// time, ppm (default 0; the realistic twin [`REALISTIC_CHIP_CLOCK_PPM`]).
    pub chip_clock_error_ppm: f64,
    /// IMU noise of this model instead of the robot's white Σ_z (default
    /// `None`); with the ideal chip drawn per firmware read, in datasheet
    /// mode per internal update of each sensor.
    pub imu_noise: Option<NoiseModel>,
    /// Bias and temperature warm-up from the board's power-up (default
    /// `None`: constant biases, 25 °C).
    pub warm_up: Option<WarmUp>,
    /// The IMU signal from the independent URDF-style chain with these
    /// hidden effects ([`crate::arm_physics`]) instead of the measurement
    /// model (default `None`).
    pub arm_physics: Option<ArmEffects>,
    /// A second BNO055 on the board's bus (docs/model.md §9: IMU 1), with
    /// its own hidden IMU parameters (default `None`).
    pub second_imu: Option<SecondImu>,
}

/// The second IMU of a two-sensor board: its own flange position
/// (ε_n1..3, so it sees another lever arm), τ (forced to 0 like IMU 0's)
/// and 24 sensor parameters, its own noise and chip clock; the robot
/// errors and gravity are IMU 0's (shared, docs/model.md §9).
#[derive(Clone, Debug)]
pub struct SecondImu {
    /// A full x ([`ParamLayout::new`] order) of which only IMU 1's own
    /// entries ([`per_imu_indices`]) are used.
    pub truth: Vec<f64>,
    /// Its chip's internal clock rate error, ppm (datasheet mode).
    pub chip_clock_error_ppm: f64,
}

/// Another IMU board on the same flange, on its own pseudo-terminal
/// (docs/model.md §9: `robimu record --imu PORT --imu PORT2`): one sensor
/// with its own position, τ and sensor parameters ([`SecondImu`]) and its
/// own clock offset and drift.
#[derive(Clone, Debug)]
pub struct ExtraBoard {
    /// Its sensor.
    pub imu: SecondImu,
    /// Its clock at start, µs.
    pub clock_offset_us: u64,
    /// Its clock rate error, ppm.
    pub clock_drift_ppm: f64,
}

impl ExtraBoard {
    /// A board whose sensor's own parameters are drawn from `robot`'s
    /// priors (`seed`), its clock `clock_offset_us` ahead and
    /// `clock_drift_ppm` fast.
    pub fn drawn(robot: &Robot, seed: u64, clock_offset_us: u64, clock_drift_ppm: f64) -> Self {
        let layout = ParamLayout::new(robot);
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        Self {
            imu: SecondImu {
                truth: draw_truth(&layout, &mut rng),
                chip_clock_error_ppm: 0.0,
            },
            clock_offset_us,
            clock_drift_ppm,
        }
    }
}

/// The indices in x of one IMU's own parameters (docs/model.md §9): its
/// flange position ε_n1..3, τ and the 24 sensor parameters.
pub(crate) fn per_imu_indices(robot: &Robot, layout: &ParamLayout) -> Vec<usize> {
    let n = robot.dof();
    let mount: Vec<String> = (1..=3).map(|k| format!("eps_{n}_{k}")).collect();
    let tau = layout.offsets().tau;
    layout
        .specs()
        .iter()
        .enumerate()
        .filter(|(i, s)| *i >= tau || mount.contains(&s.name))
        .map(|(i, _)| i)
        .collect()
}

impl SimRigConfig {
    /// `robot` with a truth drawn from its priors (seeded), a 20 ms tracking
    /// lag, and a device clock 1.234 s ahead running 48.7 ppm fast.
    pub fn drawn(robot: Robot, seed: u64) -> Self {
        let layout = ParamLayout::new(&robot);
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let truth = draw_truth(&layout, &mut rng);
        let initial = std::array::from_fn(|j| {
            robot
                .limits()
                .get(j)
                .map_or(0.0, |l| 0.5 * (l.q_min + l.q_max))
        });
        Self {
            robot,
            truth,
            initial,
            seed,
            clock_offset_us: 1_234_000,
            clock_drift_ppm: 48.7,
            tracking_lag_s: 0.02,
            chip: ChipModel::Ideal,
            chip_clock_error_ppm: 0.0,
            imu_noise: None,
            warm_up: None,
            arm_physics: None,
            second_imu: None,
        }
    }

    /// [`Self::drawn`] with a second IMU on the board whose own parameters
    /// are drawn from the priors too (its own seed).
    pub fn drawn_two_imus(robot: Robot, seed: u64) -> Self {
        let mut config = Self::drawn(robot, seed);
        let layout = ParamLayout::new(&config.robot);
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed ^ 0x1_0001);
        config.second_imu = Some(SecondImu {
            truth: draw_truth(&layout, &mut rng),
            chip_clock_error_ppm: 0.0,
        });
        config
    }

    /// The realistic twin at its defaults (issue 15; docs/model.md §4.8):
    /// [`Self::drawn`] with the datasheet chip at the power-on bandwidths,
    /// accelerometer vibration noise ([`REALISTIC_VIBRATION`]), a warm-up
    /// ([`REALISTIC_WARM_UP`]) and the arm's hidden effects
    /// ([`realistic_arm_effects`]: joints 2 and 3 elastic, a 12 Hz mount mode).
    pub fn realistic(robot: Robot, seed: u64) -> Result<Self, RigError> {
        let mut config = Self::realistic_null(robot, seed)?;
        config.warm_up = Some(REALISTIC_WARM_UP);
        config.arm_physics = Some(realistic_arm_effects(&config.robot));
        Ok(config)
    }

    /// The realistic twin with its hidden effects off: the datasheet chip
    /// (its filter delays are the chip's physics, in the truth as τ and
    /// `sensor_delay`, docs/model.md §4.8) with its internal clock
    /// [`REALISTIC_CHIP_CLOCK_PPM`] fast, and the vibration noise, no
    /// warm-up, the estimator's own chain without elasticity or mode.
    pub fn realistic_null(robot: Robot, seed: u64) -> Result<Self, RigError> {
        let mut config = Self::drawn(robot, seed);
        config.chip = ChipModel::Datasheet;
        config.chip_clock_error_ppm = REALISTIC_CHIP_CLOCK_PPM;
        let (phi, motion) = REALISTIC_VIBRATION;
        config.with_vibration_noise(phi, motion)
    }

    /// Accelerometer noise dominated by the arm's vibration (issue 14's
    /// model, docs/model.md §4.6): each accelerometer channel AR(1) with
    /// coefficient `phi` and the robot's σ at rest, its variance growing
    /// as σ² + `motion`·‖q̈‖²; the gyroscope stays white.
    pub fn with_vibration_noise(mut self, phi: f64, motion: f64) -> Result<Self, RigError> {
        self.imu_noise = Some(vibration_noise(self.robot.sigma_z(), phi, motion)?);
        Ok(self)
    }
}

/// The realistic twin's chip clock error, ppm: +0.8 %, **assumed** (a
/// plausible internal-oscillator error within the ±2 % the read-rate rule
/// allows for, `robimu_protocol::alias`; the datasheet gives no figure for
/// AMG mode that we know of), so that the twin's reads beat against the
/// chip's updates as on a real board.
pub(crate) const REALISTIC_CHIP_CLOCK_PPM: f64 = 8_000.0;

/// The realistic twin's accelerometer noise (φ, c) of
/// [`SimRigConfig::with_vibration_noise`]: AR(1) with a 30 ms correlation
/// time per internal update at 125 Hz (φ = e^(−8/30) ≈ 0.77) and a level
/// σ² + 0.3‖q̈‖² (the motion case of the Monte Carlo of docs/guide/calibrating.md).
pub const REALISTIC_VIBRATION: (f64, f64) = (0.766, 0.3);

/// The realistic twin's warm-up: 300 s from 30 °C to 40 °C, the biases
/// settling by the paper's observed drift (0.017 m/s², 0.025 °/s) and
/// smaller ones on the other axes.
pub const REALISTIC_WARM_UP: WarmUp = WarmUp {
    time_constant_s: 300.0,
    temp_start_c: 30.0,
    temp_end_c: 40.0,
    bias_start_offset: [0.017, -0.012, 0.010, 0.025 * DEG, -0.018 * DEG, 0.012 * DEG],
};

const DEG: f64 = std::f64::consts::PI / 180.0;

/// Compliance of the realistic twin's elastic joints (2 and 3), rad/(N·m):
/// 50 °/(kN·m).
pub(crate) const REALISTIC_COMPLIANCE: f64 = 50.0 * DEG * 1e-3;

/// The realistic twin's arm: joints 2 and 3 deflecting under their gravity
/// load by [`REALISTIC_COMPLIANCE`] (the catalogue's mass model, so
/// `joint_elasticity` can represent it exactly) and the default 12 Hz
/// structural mode of the IMU mount ([`StructuralMode::default`]).
pub(crate) fn realistic_arm_effects(robot: &Robot) -> ArmEffects {
    let compliance = (0..robot.dof())
        .map(|j| {
            if j == 1 || j == 2 {
                REALISTIC_COMPLIANCE
            } else {
                0.0
            }
        })
        .collect();
    ArmEffects {
        elasticity: Some(Elasticity {
            mass: robimu_model::effects::MassModel::for_robot(robot),
            compliance,
        }),
        mode: Some(StructuralMode::default()),
    }
}

/// A running rig; stops when dropped.
pub struct SimRig {
    /// The simulated controller.
    pub aubo: SimAubo,
    /// The simulated IMU board.
    pub device: SimDevice,
    /// More IMU boards ([`Self::spawn_boards`]), in IMU order.
    pub boards: Vec<SimDevice>,
    truth: Truth,
}

impl SimRig {
    /// Starts the controller and the board.
    pub fn spawn(config: &SimRigConfig) -> Result<SimRig, RigError> {
        Self::spawn_boards(config, &[])
    }

    /// Starts the controller, the board and one more board per `extra`
    /// (docs/model.md §9: their sensors are the IMUs after the first
    /// board's, in this order, `imu<j>/` in the truth).
    pub fn spawn_boards(config: &SimRigConfig, extra: &[ExtraBoard]) -> Result<SimRig, RigError> {
        check_joints(&config.robot)?;
        // The controller's own limits are the hardware's (wider than a
        // plan's), as on the real arm.
        let aubo = SimAubo::spawn(aubo_config(config))?;
        let motion = || Box::new(aubo.state_probe()) as Box<dyn TrueMotion>;
        let (device, mut truth) = imu_board(config, &motion)?;
        let mut boards = Vec::with_capacity(extra.len());
        let first = 1 + usize::from(config.second_imu.is_some());
        for (b, board) in extra.iter().enumerate() {
            let j = first + b;
            let (source, own) = second_imu_source(config, &board.imu, j, motion())?;
            truth.values.extend(own.values);
            let mut device_config = SimDeviceConfig::new(Box::new(source));
            device_config.chip_model = config.chip;
            device_config.chip_clock_error_ppm = board.imu.chip_clock_error_ppm;
            device_config.clock_offset_us = board.clock_offset_us;
            device_config.clock_drift_ppm = board.clock_drift_ppm;
            device_config.fault_seed = config.seed ^ 0xFA17 ^ ((j as u64) << 32);
            boards.push(SimDevice::spawn(device_config)?);
        }
        Ok(SimRig {
            aubo,
            device,
            boards,
            truth,
        })
    }

    /// The IMU board's serial port (a pseudo-terminal path).
    pub fn imu_port(&self) -> &str {
        self.device.port_path()
    }

    /// The serial ports of the boards after the first, in IMU order.
    pub fn extra_imu_ports(&self) -> Vec<String> {
        self.boards
            .iter()
            .map(|d| d.port_path().to_string())
            .collect()
    }

    /// The controller's address.
    pub fn robot_addr(&self) -> SocketAddr {
        self.aubo.addr()
    }

    /// `aubo:HOST:PORT` for `robimu record --robot`.
    pub fn robot_spec(&self) -> String {
        format!("aubo:{}", self.aubo.addr())
    }

    /// The hidden truth (τ = 0), as `truth.toml` lists it.
    pub fn truth(&self) -> &Truth {
        &self.truth
    }
}

/// The rig simulates 6-joint arms.
pub(crate) fn check_joints(robot: &Robot) -> Result<(), RigError> {
    if robot.dof() != JOINTS {
        return Err(RigError::Joints {
            name: robot.name().to_string(),
            dof: robot.dof(),
        });
    }
    Ok(())
}

/// The simulated IMU board on the flange of the arm `motion` reads, at the
/// hidden truth (τ forced to 0).
fn imu_board(
    config: &SimRigConfig,
    motion: &dyn Fn() -> Box<dyn TrueMotion>,
) -> Result<(SimDevice, Truth), RigError> {
    let (source, mut truth) = imu_source(config, motion())?;
    let mut device_config = SimDeviceConfig::new(Box::new(source));
    if let Some(second) = &config.second_imu {
        let (source, own) = second_imu_source(config, second, 1, motion())?;
        truth.values.extend(own.values);
        device_config.second = Some(SecondSensor {
            source: Box::new(source),
            chip_clock_error_ppm: second.chip_clock_error_ppm,
        });
    }
    device_config.chip_model = config.chip;
    device_config.chip_clock_error_ppm = config.chip_clock_error_ppm;
    device_config.clock_offset_us = config.clock_offset_us;
    device_config.clock_drift_ppm = config.clock_drift_ppm;
    device_config.fault_seed = config.seed ^ 0xFA17;
    let device = SimDevice::spawn(device_config)?;
    Ok((device, truth))
}

/// What the IMU on the flange of the arm `motion` reads ([`ModelSource`]
/// with the config's noise, warm-up and arm physics) at the hidden truth
/// (τ forced to 0), and that truth: shared by the real-time rig and the
/// virtual-time twin ([`crate::twin`]).
pub(crate) fn imu_source(
    config: &SimRigConfig,
    motion: Box<dyn TrueMotion>,
) -> Result<(ModelSource, Truth), RigError> {
    let robot = &config.robot;
    let layout = ParamLayout::new(robot);
    let mut x = config.truth.clone();
    if let Some(tau) = x.get_mut(layout.offsets().tau) {
        *tau = 0.0;
    }
    let model = MeasurementModel::new(robot, &layout, &x)?;
    let mut source = ModelSource::new(motion, model, robot.sigma_z(), config.seed);
    if let Some(noise) = &config.imu_noise {
        source = source.with_noise_model(noise.clone());
    }
    if let Some(warm_up) = config.warm_up {
        source = source.with_warm_up(warm_up);
    }
    if let Some(effects) = &config.arm_physics {
        let arm = UrdfArm::from_model(robot, &layout, &x)?;
        source = source.with_arm_physics(ArmPhysics::new(arm, effects.clone(), robot.gravity())?);
    }
    let truth = Truth {
        values: layout
            .specs()
            .iter()
            .zip(&x)
            .map(|(s, v)| (s.name.clone(), *v))
            .collect(),
    };
    Ok((source, truth))
}

/// IMU `j` ≥ 1 (the second sensor of a board, or another board's):
/// [`imu_source`] at IMU 0's truth with `second`'s own entries (and its
/// own noise seed); its truth as `imu<j>/<name>` for those entries
/// (docs/model.md §9).
fn second_imu_source(
    config: &SimRigConfig,
    second: &SecondImu,
    j: usize,
    motion: Box<dyn TrueMotion>,
) -> Result<(ModelSource, Truth), RigError> {
    let layout = ParamLayout::new(&config.robot);
    if second.truth.len() != layout.len() {
        return Err(RigError::Model(ModelError::ParamLength(
            robimu_model::params::ParamLengthError {
                expected: layout.len(),
                found: second.truth.len(),
            },
        )));
    }
    let own = per_imu_indices(&config.robot, &layout);
    let mut x = config.truth.clone();
    for &i in &own {
        x[i] = second.truth[i];
    }
    let imu1 = SimRigConfig {
        truth: x,
        seed: config.seed ^ 0x05EC_00D1 ^ ((j as u64 - 1) << 40),
        chip_clock_error_ppm: second.chip_clock_error_ppm,
        second_imu: None,
        ..config.clone()
    };
    let (source, truth) = imu_source(&imu1, motion)?;
    let values = own
        .iter()
        .map(|&i| {
            let (name, v) = &truth.values[i];
            (format!("imu{j}/{name}"), *v)
        })
        .collect();
    Ok((source, Truth { values }))
}

/// The controller's settings of the AUBO rig: the hardware's limits, the
/// config's tracking lag, the robot's Σ_q as encoder noise.
pub(crate) fn aubo_config(config: &SimRigConfig) -> SimAuboConfig {
    let robot = &config.robot;
    let sigma_q: [f64; JOINTS] = std::array::from_fn(|j| robot.sigma_q()[j]);
    SimAuboConfig {
        initial: config.initial,
        limits: JointLimits::default(),
        tracking_lag_s: config.tracking_lag_s,
        encoder_noise_per_joint: Some(sigma_q),
        seed: config.seed ^ 0xA0B0,
        ..SimAuboConfig::default()
    }
}

/// The same rig around a simulated Universal Robots controller (RTDE at
/// 125 Hz, URScript `servoj` programs; encoder noise the smallest of the
/// robot's Σ_q, as the simulator has one level for all joints).
pub struct SimUrRig {
    /// The simulated controller.
    pub ur: SimUr,
    /// The simulated IMU board.
    pub device: SimDevice,
    truth: Truth,
}

impl SimUrRig {
    /// Starts the controller and the board.
    pub fn spawn(config: &SimRigConfig) -> Result<SimUrRig, RigError> {
        check_joints(&config.robot)?;
        let noise = config
            .robot
            .sigma_q()
            .iter()
            .fold(f64::INFINITY, |m, s| m.min(*s));
        let ur = SimUr::spawn(SimUrConfig {
            control_rate_hz: 125.0,
            initial: config.initial,
            tracking_lag_s: config.tracking_lag_s,
            encoder_noise_rad: noise,
            seed: config.seed ^ 0x0B0E,
            ..SimUrConfig::default()
        })?;
        let (device, truth) = imu_board(config, &|| Box::new(ur.state_probe()))?;
        Ok(SimUrRig { ur, device, truth })
    }

    /// The IMU board's serial port.
    pub fn imu_port(&self) -> &str {
        self.device.port_path()
    }

    /// `ur:HOST:RTDE_PORT:SCRIPT_PORT` for `robimu record --robot`.
    pub fn robot_spec(&self) -> String {
        format!(
            "ur:{}:{}:{}",
            self.ur.rtde_addr().ip(),
            self.ur.rtde_addr().port(),
            self.ur.script_addr().port()
        )
    }

    /// The hidden truth (τ = 0).
    pub fn truth(&self) -> &Truth {
        &self.truth
    }
}
