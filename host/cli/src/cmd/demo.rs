//! `robimu demo`: the main job on simulated hardware. A plan, a simulated
//! AUBO i5 on loopback TCP and a simulated IMU board on a pseudo-terminal
//! (the real firmware core over a register-level BNO055 whose readings come
//! from the arm's physics at a hidden truth), a recording through the same
//! code as `robimu record` (or the same hardware in virtual time with
//! `--fast`), a calibration with the identified noise model, a diagnosis,
//! and diagnose's final model checked against the twin's truth
//! (docs/model.md §4.8). The twin is the realistic one (datasheet chip,
//! vibration noise, warm-up, elastic joints, a structural mode) unless
//! `--ideal`.
//!
//! With `--imus 2` (docs/model.md §9) the simulated board reads two BNO055
//! on its bus, each with its own hidden position, τ and sensor parameters;
//! the session is calibrated jointly and that calibration's 76 parameters
//! are checked against the truth (the demo's truth check of diagnose's
//! model covers one IMU; `robimu diagnose` diagnoses each IMU; the ideal
//! twin in real time only).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context};
use robimu_hil::rig::{SimRig, SimRigConfig};
use robimu_hil::truth::{clock_mapping_error, mode_signal, twin_truth, MotionSample};
use robimu_hil::twin::{record_offline, TwinOptions};
use robimu_model::observations::Measurements;
use robimu_model::ParamLayout;
use robimu_model::Robot;
use robimu_protocol::SensorConfig;
use robimu_record::controller::RobotSpec;
use robimu_record::motion::Plan;
use robimu_record::RecordOptions;
use robimu_report::demo::{DemoFiles, DemoHardware, DemoPlanned, DemoRecordCommand};
use robimu_report::demo::{DemoTruthCheck, TruthRow};
use robimu_session::files;
use robimu_session::result::CalibrationResult;
use robimu_session::{Session, Truth};
use robimu_workflows::calibrate::{calibrate, CalibrateOptions};
use robimu_workflows::diagnose::refit_final;
use robimu_workflows::diagnose::Diagnosis;
use robimu_workflows::plan::PlanOptions;

use super::calibrate::CalibrateCmd;
use super::input::record_with_progress;
use robimu_report::recording::RecordSummaryText;

/// Run the main job on simulated hardware, no robot or IMU needed: plan,
/// record from a simulated AUBO i5 and IMU board with a hidden truth (the
/// realistic twin unless --ideal), calibrate, diagnose, and compare
/// diagnose's final model with the truth.
#[derive(Debug, Clone, clap::Args)]
pub struct DemoCmd {
    /// Directory for the plan, the session and the result [default: a new
    /// directory under the system's temporary directory].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Length of the excitation motion, s.
    #[arg(long, default_value_t = 60.0)]
    pub duration: f64,
    /// Seed of the hidden truth, the motion and the noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The simulated board's clock drift, ppm.
    #[arg(long, default_value_t = 48.7)]
    pub drift_ppm: f64,
    /// The ideal twin instead of the realistic one: readings from the
    /// estimator's own model at the firmware's read instants, white noise,
    /// constant biases, no chip filters, no elasticity or structural mode.
    #[arg(long)]
    pub ideal: bool,
    /// Record in virtual time (the same firmware core, chip, arm motion and
    /// session writer, as fast as the computer goes) instead of in real
    /// time over a pseudo-terminal and loopback TCP.
    #[arg(long)]
    pub fast: bool,
    /// The board's sampling rate, Hz: by default the firmware's, which its
    /// rule chooses so that reads do not alias the chip's internal updates
    /// (150 Hz: the 125 Hz accelerometer's data age cycles at 25 Hz, above
    /// the motion; at the paper's 120 Hz it beats at 5 Hz, inside it:
    /// docs/model.md §4.8).
    #[arg(long, default_value_t = robimu_protocol::DEFAULT_SAMPLE_RATE_HZ)]
    pub rate: u16,
    /// How many BNO055 the simulated board reads (1 or 2; docs/model.md
    /// §9): with 2, the session has imu.csv and imu1.csv and is calibrated
    /// jointly (needs --ideal, not --fast).
    #[arg(long, default_value_t = 1)]
    pub imus: usize,
}

/// Bound of the truth check, σ.
const TRUTH_LIMIT: f64 = 4.0;

impl DemoCmd {
    /// Plan, record, calibrate.
    pub fn run(self) -> anyhow::Result<()> {
        let start = Instant::now();
        if !(self.duration.is_finite() && (5.0..=3600.0).contains(&self.duration)) {
            bail!("--duration must be in [5, 3600] s (got {})", self.duration);
        }
        if !(1..=1000).contains(&self.rate) {
            bail!("--rate must be in [1, 1000] Hz (got {})", self.rate);
        }
        if !(1..=2).contains(&self.imus) {
            bail!(
                "--imus must be 1 or 2: the simulated board reads at most two BNO055 (got {})",
                self.imus
            );
        }
        if self.imus > 1 && self.fast {
            bail!("--imus 2 records in real time: the virtual-time twin (--fast) reads one sensor");
        }
        if self.imus > 1 && !self.ideal {
            bail!(
                "--imus 2 needs --ideal: the realistic twin's truth (chip delays, warm-up) is modelled for one sensor"
            );
        }
        if let Some(warning) = robimu_record::alias_warning(&self.sensor()) {
            eprintln!("warning: {warning}");
        }
        let dir = self.out.clone().unwrap_or_else(|| {
            std::env::temp_dir().join(format!("robimu-demo-{}", std::process::id()))
        });
        let session = dir.join("session");
        if session.join(files::META).exists() {
            bail!(
                "{} already holds a session: choose another --out",
                session.display()
            );
        }
        let plan_dir = dir.join("plan");
        std::fs::create_dir_all(&plan_dir)
            .with_context(|| format!("cannot create {}", plan_dir.display()))?;
        let mut out = std::io::stdout();
        let robot = Robot::aubo_i5();

        writeln!(out, "== 1. plan ==")?;
        let plan = self.plan(&robot, &plan_dir)?;

        writeln!(out, "\n== 2. simulated hardware ==")?;
        let config = self.twin_config(&robot, &plan)?;

        writeln!(out, "\n== 3. record ==")?;
        let (plan_dir, session) = (plan_dir.as_path(), session.as_path());
        // and the session clock mapping's own error (the twin knows its
        // board's clock)
        let (powered_for, imu_time_error) = if self.fast {
            self.show_hardware(&config, None, None)?;
            let opts = TwinOptions {
                sensor: self.sensor(),
                ..TwinOptions::default()
            };
            let t0 = Instant::now();
            let s = record_offline(&config, &plan, session, &opts)
                .context("cannot record the virtual-time twin")?;
            writeln!(
                out,
                "recorded {:.1} s in virtual time in {:.1} s: {} IMU and {} joint samples into {}",
                s.duration,
                t0.elapsed().as_secs_f64(),
                s.imu_samples,
                s.joint_samples,
                session.display()
            )?;
            (s.powered_for_s, s.imu_time_error_s)
        } else {
            let powered = Instant::now();
            let rig = SimRig::spawn(&config).context("cannot start the simulated hardware")?;
            self.show_hardware(
                &config,
                Some(rig.imu_port()),
                Some(rig.robot_addr().to_string()),
            )?;
            let powered_for = powered.elapsed().as_secs_f64();
            let error = self.record(&rig, robot.clone(), plan, plan_dir, session)?;
            drop(rig);
            (powered_for, error)
        };
        // truth.toml: the twin's truth for the baseline model (§4.8), which
        // calibrate's report compares with.
        let hidden =
            Truth::read(&session.join(files::TRUTH)).context("cannot read the hidden truth")?;
        let mode = ModeShare::of(&config, session)?;
        let truth_for = |effects: &[String],
                         mode: Option<&[(String, f64)]>|
         -> anyhow::Result<robimu_hil::truth::TwinTruth> {
            let s = Session::load(session)?;
            let timing = s.meta.imu_timing(&session.join(files::META))?;
            let since: Vec<f64> = s
                .measurements()
                .imu_t
                .iter()
                .map(|t| t + powered_for)
                .collect();
            Ok(twin_truth(
                &config,
                &hidden,
                timing.as_ref(),
                &since,
                effects,
                mode,
                imu_time_error,
            ))
        };
        let baseline = truth_for(&[], mode.as_ref().map(|m| m.baseline.as_slice()))?;
        let path = session.join(files::TRUTH);
        std::fs::write(
            &path,
            Truth {
                values: baseline.values.clone(),
            }
            .to_toml(),
        )
        .with_context(|| format!("cannot write {}", path.display()))?;

        writeln!(out, "\n== 4. calibrate ==")?;
        out.flush()?;
        let t0 = Instant::now();
        let report = dir.join("report");
        self.calibrate(session, &report)?;
        writeln!(out, "calibration took {:.1} s", t0.elapsed().as_secs_f64())?;

        let check = if self.imus > 1 {
            writeln!(out, "\n== 5. diagnose ==")?;
            writeln!(
                out,
                "skipped: the demo checks diagnose's model against the truth for one IMU; the {} IMUs' joint calibration is checked (`robimu diagnose SESSION` diagnoses each IMU)",
                self.imus
            )?;
            writeln!(out, "\n== 6. against the truth ==")?;
            self.joint_truth_check(
                session,
                &truth_for(&[], mode.as_ref().map(|m| m.baseline.as_slice()))?,
            )?
        } else {
            writeln!(out, "\n== 5. diagnose ==")?;
            out.flush()?;
            let t0 = Instant::now();
            let d = self.diagnose(session, &dir.join("diagnosis"))?;
            writeln!(out, "diagnosis took {:.1} s", t0.elapsed().as_secs_f64())?;

            writeln!(out, "\n== 6. against the truth ==")?;
            let names: Vec<String> = d
                .final_fit
                .effect_params
                .iter()
                .map(|p| p.name.clone())
                .collect();
            let share = match &mode {
                Some(m) => Some(m.of_final(&robot, &d)?),
                None => None,
            };
            self.truth_check(&robot, &d, &truth_for(&names, share.as_deref())?)
        };
        write!(out, "{check}")?;
        std::fs::create_dir_all(&report)
            .with_context(|| format!("cannot create {}", report.display()))?;
        let path = report.join("truth_check.json");
        std::fs::write(&path, serde_json::to_string_pretty(&check.to_json())?)
            .with_context(|| format!("cannot write {}", path.display()))?;
        let text = report.join("truth_check.txt");
        std::fs::write(&text, check.to_string())
            .with_context(|| format!("cannot write {}", text.display()))?;
        writeln!(out, "wrote {} and {}", path.display(), text.display())?;
        let seconds = start.elapsed().as_secs_f64();
        let report = report.as_path();
        write!(
            out,
            "{}",
            DemoFiles {
                plan_dir,
                session,
                report,
                seconds
            }
        )?;
        Ok(())
    }

    /// Plans the excitation, writes PLAN_DIR/plan.csv and says so.
    fn plan(&self, robot: &Robot, plan_dir: &Path) -> anyhow::Result<Plan> {
        let progress = super::input::Progress::start("planning");
        let t0 = Instant::now();
        let opts = PlanOptions {
            duration: self.duration,
            seed: self.seed,
            ..PlanOptions::default()
        };
        let planned = robimu_workflows::plan::plan(robot, &opts, |b, nb, l| {
            progress.set_message(format!("planning: block {b}/{nb}, λ_max ≈ {l:.3e}"))
        })
        .context("cannot plan the excitation trajectory")?;
        progress.finish();
        let plan = Plan::from_spline(&planned.spline, 250.0);
        let path = plan_dir.join("plan.csv");
        plan.write_csv(&path)
            .with_context(|| format!("cannot write {}", path.display()))?;
        let planned = DemoPlanned {
            duration: self.duration,
            seconds: t0.elapsed().as_secs_f64(),
            lambda_max: planned.lambda_max.last().copied().unwrap_or(f64::NAN),
            path: &path,
            waypoints: plan.q.len(),
        };
        write!(std::io::stdout(), "{planned}")?;
        Ok(plan)
    }

    /// The twin: realistic (docs/model.md §4.8) unless `--ideal`, the truth
    /// drawn from the priors, the arm waiting at the plan's first pose (a
    /// real one is moved there first: `record` does that at half the
    /// slowest joint's limits).
    fn twin_config(&self, robot: &Robot, plan: &Plan) -> anyhow::Result<SimRigConfig> {
        let mut config = if self.imus > 1 {
            SimRigConfig::drawn_two_imus(robot.clone(), self.seed)
        } else if self.ideal {
            SimRigConfig::drawn(robot.clone(), self.seed)
        } else {
            SimRigConfig::realistic(robot.clone(), self.seed)?
        };
        config.clock_drift_ppm = self.drift_ppm;
        config.initial = plan.q[0];
        Ok(config)
    }

    /// The board's settings: the defaults at `--rate`.
    fn sensor(&self) -> SensorConfig {
        SensorConfig {
            sample_rate_hz: self.rate,
            ..SensorConfig::default()
        }
    }

    /// Says what simulated hardware runs.
    fn show_hardware(
        &self,
        config: &SimRigConfig,
        imu_port: Option<&str>,
        robot_addr: Option<String>,
    ) -> anyhow::Result<()> {
        let twin = if self.ideal {
            "ideal (readings from the estimator's model at each firmware read, white noise Σ_z)"
                .to_string()
        } else {
            let (phi, c) = robimu_hil::rig::REALISTIC_VIBRATION;
            format!(
                "realistic ({:?} chip: own ODR clocks ({:+.1} % against the arm's time) and filters, read at {} Hz; accelerometer vibration noise AR(1) φ = {phi}, σ² + {c}‖q̈‖²; warm-up over {} s; joints 2, 3 elastic; {} Hz structural mode)",
                config.chip,
                config.chip_clock_error_ppm * 1e-4,
                self.rate,
                robimu_hil::rig::REALISTIC_WARM_UP.time_constant_s,
                config
                    .arm_physics
                    .as_ref()
                    .and_then(|a| a.mode)
                    .map_or(0.0, |m| m.frequency_hz)
            )
        };
        let twin = if self.imus > 1 {
            format!("{twin}; two BNO055 on the board's bus (0x28: IMU 0, 0x29: IMU 1, each its own position, τ and sensor errors; docs/model.md §9)")
        } else {
            twin
        };
        let hardware = DemoHardware {
            imu_port,
            drift_ppm: self.drift_ppm,
            robot_addr,
            seed: self.seed,
            twin: &twin,
        };
        write!(std::io::stdout(), "{hardware}")?;
        Ok(())
    }

    /// `robimu diagnose SESSION --out DIR` (noise model auto).
    fn diagnose(&self, session: &Path, out: &Path) -> anyhow::Result<Diagnosis> {
        super::diagnose::DiagnoseCmd {
            session: session.to_path_buf(),
            calibration: None,
            out: Some(out.to_path_buf()),
            alpha: 0.01,
            mass_model: None,
            candidates: Vec::new(),
            resonance: Default::default(),
            noise_model: "auto".into(),
        }
        .run_diagnosis()
    }

    /// Every estimated parameter of diagnose's final model against `truth`.
    fn truth_check(
        &self,
        robot: &Robot,
        d: &Diagnosis,
        truth: &robimu_hil::truth::TwinTruth,
    ) -> DemoTruthCheck {
        let fit = &d.final_fit;
        let layout = ParamLayout::new(robot);
        let mut rows = Vec::new();
        for (k, spec) in layout.specs().iter().enumerate() {
            if let (Some(t), true) = (truth.get(&spec.name), fit.sigma_x[k] > 0.0) {
                rows.push(TruthRow {
                    name: spec.name.clone(),
                    estimate: fit.x[k],
                    sigma: fit.sigma_x[k],
                    truth: t,
                    mode_share: truth.mode_share(&spec.name),
                });
            }
        }
        for (i, p) in fit.effect_params.iter().enumerate() {
            if let Some(t) = truth.get(&p.name) {
                rows.push(TruthRow {
                    name: p.name.clone(),
                    estimate: fit.theta_e[i],
                    sigma: fit.sigma_e[i],
                    truth: t,
                    mode_share: truth.mode_share(&p.name),
                });
            }
        }
        DemoTruthCheck {
            model: "diagnose's final model".into(),
            twin: if self.ideal { "ideal" } else { "realistic" }.into(),
            effects: fit.effects.clone(),
            rows,
            not_comparable: truth.not_comparable.clone(),
            limit: TRUTH_LIMIT,
        }
    }

    /// The joint calibration's result (SESSION/result.json, docs/model.md
    /// §9) against `truth`: every estimated parameter of every IMU.
    fn joint_truth_check(
        &self,
        session: &Path,
        truth: &robimu_hil::truth::TwinTruth,
    ) -> anyhow::Result<DemoTruthCheck> {
        let path = session.join("result.json");
        let result = CalibrationResult::read(&path)
            .with_context(|| format!("cannot read the calibration {}", path.display()))?;
        let rows = result
            .parameters
            .iter()
            .filter(|p| !p.frozen && p.sigma > 0.0)
            .filter_map(|p| {
                Some(TruthRow {
                    name: p.name.clone(),
                    estimate: p.value,
                    sigma: p.sigma,
                    truth: truth.get(&p.name)?,
                    mode_share: truth.mode_share(&p.name),
                })
            })
            .collect();
        Ok(DemoTruthCheck {
            model: format!("the joint calibration of {} IMUs", self.imus),
            twin: "ideal".into(),
            effects: Vec::new(),
            rows,
            not_comparable: truth.not_comparable.clone(),
            limit: TRUTH_LIMIT,
        })
    }

    /// Records the plan from `rig` into `session` as `robimu record` does,
    /// with the hidden truth beside it; returns the session clock mapping's
    /// error at its middle (the IMU samples' true session times minus the
    /// session's, docs/model.md §4.8).
    fn record(
        &self,
        rig: &SimRig,
        robot: Robot,
        plan: Plan,
        plan_dir: &Path,
        session: &Path,
    ) -> anyhow::Result<f64> {
        let robot_spec = rig.robot_spec();
        let command = DemoRecordCommand {
            imu_port: rig.imu_port(),
            robot_spec: &robot_spec,
            plan_dir,
            session,
        };
        write!(std::io::stdout(), "{command}")?;
        let opts = RecordOptions {
            imu_port: rig.imu_port().to_string(),
            extra_imu_ports: Vec::new(),
            baud: 921_600,
            robot_spec: RobotSpec::parse(&robot_spec)?,
            robot,
            robot_name: "aubo_i5".into(),
            plan: Some(plan),
            duration: self.duration,
            out: session.to_path_buf(),
            joint_rate: 125.0,
            rest: 1.0,
            sensor: self.sensor(),
            interrupt: None,
        };
        let summary = record_with_progress(&opts)?;
        print!("{}", RecordSummaryText(&summary));
        print!("{}", super::record::imu_lines(&summary));
        let truth = session.join(files::TRUTH);
        std::fs::write(&truth, rig.truth().to_toml())
            .with_context(|| format!("cannot write {}", truth.display()))?;
        // the board's true clock at the session's middle against the time
        // the session's clock fit gives it
        let middle = summary.duration / 2.0;
        let at = summary.epoch + std::time::Duration::from_secs_f64(middle);
        let device = rig.device.clock().device_us_at(at) * 1e-6;
        Ok(clock_mapping_error(&summary.clock, middle, device))
    }

    /// `robimu calibrate SESSION --report REPORT`.
    fn calibrate(&self, session: &Path, report: &Path) -> anyhow::Result<()> {
        CalibrateCmd {
            session: session.to_path_buf(),
            out: None,
            windows: None,
            report: Some(report.to_path_buf()),
            fit: Default::default(),
        }
        .run()
    }
}

/// The twin's structural mode in a session (docs/model.md §4.8): the
/// session's samples with the mode's part of the signal taken out, and its
/// share of the baseline calibration. A model's share of the mode is its
/// estimate minus its estimate from those samples: what it absorbs of an
/// effect it does not have, which the truth it is compared with includes.
struct ModeShare {
    /// The session's samples without the mode's signal.
    still: Measurements,
    /// The calibration options of the session.
    opts: CalibrateOptions,
    /// Per parameter of x: the baseline calibration's share.
    baseline: Vec<(String, f64)>,
}

impl ModeShare {
    /// None when the twin has no mode. The mode's signal ([`mode_signal`])
    /// follows the baseline calibration's trajectory at each IMU sample.
    fn of(config: &SimRigConfig, session: &Path) -> anyhow::Result<Option<Self>> {
        if config.arm_physics.as_ref().is_none_or(|a| a.mode.is_none()) {
            return Ok(None);
        }
        let s = Session::load(session)?;
        let data = s.measurements();
        let robot = &config.robot;
        let n = robot.dof();
        let mut opts = CalibrateOptions::new(robot);
        (opts.sigma_z, opts.sigma_q) = s.noise(robot)?;
        let with =
            calibrate(robot, &data, &opts, |_| {}).context("cannot calibrate for the truth")?;
        let layout = ParamLayout::new(robot);
        let (tau, spline) = (with.x[layout.offsets().tau], &with.trajectory);
        let mut js = robimu_model::JointState::default();
        let (index, motion): (Vec<usize>, Vec<MotionSample>) = data
            .imu_t
            .iter()
            .enumerate()
            .filter(|(_, &t)| spline.knots().contains(t + tau))
            .map(|(i, &t)| {
                spline.evaluate_clamped(t + tau, &mut js);
                let sample = MotionSample {
                    t,
                    q: js.q[..n].to_vec(),
                    qd: js.qd[..n].to_vec(),
                    qdd: js.qdd[..n].to_vec(),
                };
                (i, sample)
            })
            .unzip();
        let Some(dz) = mode_signal(config, &motion)? else {
            return Ok(None);
        };
        let mut still = data.clone();
        for (&i, d) in index.iter().zip(&dz) {
            for (z, d) in still.imu_z[i].iter_mut().zip(d) {
                *z -= d;
            }
        }
        let without =
            calibrate(robot, &still, &opts, |_| {}).context("cannot calibrate for the truth")?;
        let baseline = differences(&layout, &with.x, &without.x, &[], &[], &[]);
        Ok(Some(Self {
            still,
            opts,
            baseline,
        }))
    }

    /// The share of diagnose's final model: its estimate minus its refit
    /// to the samples without the mode.
    fn of_final(&self, robot: &Robot, d: &Diagnosis) -> anyhow::Result<Vec<(String, f64)>> {
        let f = &d.final_fit;
        let without = refit_final(robot, &self.still, &self.opts, d)
            .context("cannot refit diagnose's model for the truth")?;
        let names: Vec<String> = f.effect_params.iter().map(|p| p.name.clone()).collect();
        Ok(differences(
            &ParamLayout::new(robot),
            &f.x,
            &without.x,
            &names,
            &f.theta_e,
            &without.theta_e,
        ))
    }
}

/// (name, a − b) of every parameter of x and every effect parameter.
fn differences(
    layout: &ParamLayout,
    x_a: &[f64],
    x_b: &[f64],
    effect_names: &[String],
    e_a: &[f64],
    e_b: &[f64],
) -> Vec<(String, f64)> {
    let x = layout
        .specs()
        .iter()
        .map(|s| s.name.clone())
        .zip(x_a.iter().zip(x_b));
    let e = effect_names.iter().cloned().zip(e_a.iter().zip(e_b));
    x.chain(e).map(|(n, (a, b))| (n, a - b)).collect()
}
