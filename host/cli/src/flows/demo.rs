//! The demo as the program runs it (`robimu demo`): plan, simulated
//! hardware, record, calibrate, diagnose, and the result against the twin's
//! hidden truth (docs/model.md §4.8; the truth's computation is
//! [`robimu_hil::truth_check`]).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context};
use robimu_hil::rig::{SimRig, SimRigConfig};
use robimu_hil::truth::{clock_mapping_error, TwinTruth};
use robimu_hil::truth_check::{fitted_check, result_rows, session_truth, ModeShare};
use robimu_hil::twin::{record_offline, TwinOptions};
use robimu_model::Robot;
use robimu_protocol::SensorConfig;
use robimu_record::controller::RobotSpec;
use robimu_record::motion::Plan;
use robimu_record::RecordOptions;
use robimu_report::demo::DemoTruthCheck;
use robimu_report::demo::{DemoFiles, DemoHardware, DemoPlanned, DemoRecordCommand};
use robimu_report::recording::RecordSummaryText;
use robimu_session::files;
use robimu_session::result::CalibrationResult;
use robimu_session::{Truth, TruthRow};
use robimu_workflows::diagnose::Diagnosis;
use robimu_workflows::plan::PlanOptions;
use robimu_workflows::Fitted;

use crate::input::{record_with_progress, Progress};

/// The demo's settings (`robimu demo`'s flags).
#[derive(Debug, Clone, clap::Args)]
pub struct DemoArgs {
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

/// Where the recording's hidden truth stands: how long the board ran before
/// the session's first sample, and the session clock mapping's error.
struct Recorded {
    powered_for: f64,
    imu_time_error: f64,
}

impl DemoArgs {
    /// Plan, record, calibrate, diagnose, check against the truth.
    pub fn run(&self) -> anyhow::Result<()> {
        let start = Instant::now();
        self.check()?;
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
        let recorded = self.record_session(&config, &robot, plan, plan_dir, session)?;
        // truth.toml: the twin's truth for the baseline model (§4.8), which
        // calibrate's report compares with.
        let hidden =
            Truth::read(&session.join(files::TRUTH)).context("cannot read the hidden truth")?;
        let mode = ModeShare::of(&config, session)?;
        let truth_for = |effects: &[String], mode: Option<&[(String, f64)]>| {
            let r = &recorded;
            session_truth(
                &config,
                &hidden,
                session,
                r.powered_for,
                r.imu_time_error,
                effects,
                mode,
            )
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
        let fitted = self.calibrate(session, &report)?;
        writeln!(out, "calibration took {:.1} s", t0.elapsed().as_secs_f64())?;

        let check = if self.imus > 1 {
            self.joint_check(&mut out, session, &baseline)?
        } else {
            writeln!(out, "\n== 5. diagnose ==")?;
            out.flush()?;
            let t0 = Instant::now();
            self.diagnose(session, &dir.join("diagnosis"))?;
            writeln!(out, "diagnosis took {:.1} s", t0.elapsed().as_secs_f64())?;

            writeln!(out, "\n== 6. against the truth ==")?;
            let c = fitted_check(&robot, &fitted, mode.as_ref(), truth_for)?;
            self.truth_check(c.effects, c.rows, &c.truth)
        };
        write_check(&mut out, &check, &report)?;
        let seconds = start.elapsed().as_secs_f64();
        let report = report.as_path();
        let next = next_step(&fitted, session);
        write!(
            out,
            "{}",
            DemoFiles {
                plan_dir,
                session,
                report,
                seconds,
                result: &fitted.result,
                next: &next,
            }
        )?;
        Ok(())
    }

    /// The flags checked.
    fn check(&self) -> anyhow::Result<()> {
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
        Ok(())
    }

    /// Records the plan in virtual time (`--fast`) or in real time from the
    /// simulated hardware; returns where the hidden truth stands.
    fn record_session(
        &self,
        config: &SimRigConfig,
        robot: &Robot,
        plan: Plan,
        plan_dir: &Path,
        session: &Path,
    ) -> anyhow::Result<Recorded> {
        if self.fast {
            self.show_hardware(config, None, None)?;
            let opts = TwinOptions {
                sensor: self.sensor(),
                ..TwinOptions::default()
            };
            let t0 = Instant::now();
            let s = record_offline(config, &plan, session, &opts)
                .context("cannot record the virtual-time twin")?;
            writeln!(
                std::io::stdout(),
                "recorded {:.1} s in virtual time in {:.1} s: {} IMU and {} joint samples into {}",
                s.duration,
                t0.elapsed().as_secs_f64(),
                s.imu_samples,
                s.joint_samples,
                session.display()
            )?;
            return Ok(Recorded {
                powered_for: s.powered_for_s,
                imu_time_error: s.imu_time_error_s,
            });
        }
        let powered = Instant::now();
        let rig = SimRig::spawn(config).context("cannot start the simulated hardware")?;
        self.show_hardware(
            config,
            Some(rig.imu_port()),
            Some(rig.robot_addr().to_string()),
        )?;
        let powered_for = powered.elapsed().as_secs_f64();
        let imu_time_error = self.record(&rig, robot.clone(), plan, plan_dir, session)?;
        Ok(Recorded {
            powered_for,
            imu_time_error,
        })
    }

    /// With several IMUs: the joint calibration's result against the truth
    /// (diagnose is skipped).
    fn joint_check(
        &self,
        out: &mut impl Write,
        session: &Path,
        truth: &TwinTruth,
    ) -> anyhow::Result<DemoTruthCheck> {
        writeln!(out, "\n== 5. diagnose ==")?;
        writeln!(
            out,
            "skipped: the demo checks diagnose's model against the truth for one IMU; the {} IMUs' joint calibration is checked (`robimu diagnose SESSION` diagnoses each IMU)",
            self.imus
        )?;
        writeln!(out, "\n== 6. against the truth ==")?;
        let path = session.join("result.json");
        let result = CalibrationResult::read(&path)
            .with_context(|| format!("cannot read the calibration {}", path.display()))?;
        Ok(DemoTruthCheck {
            model: format!("the joint calibration of {} IMUs", self.imus),
            twin: "ideal".into(),
            effects: Vec::new(),
            rows: result_rows(&result, truth),
            not_comparable: truth.not_comparable.clone(),
            limit: TRUTH_LIMIT,
        })
    }

    /// The result calibrate wrote (its model's `effects` and `rows`)
    /// against the truth of that model.
    fn truth_check(
        &self,
        effects: Vec<String>,
        rows: Vec<TruthRow>,
        truth: &TwinTruth,
    ) -> DemoTruthCheck {
        DemoTruthCheck {
            model: "calibrate's result".into(),
            twin: if self.ideal { "ideal" } else { "realistic" }.into(),
            effects,
            rows,
            not_comparable: truth.not_comparable.clone(),
            limit: TRUTH_LIMIT,
        }
    }

    /// `robimu calibrate SESSION --report REPORT`.
    fn calibrate(&self, session: &Path, report: &Path) -> anyhow::Result<Fitted> {
        crate::flows::calibrate::CalibrateRun {
            session,
            out: None,
            windows: None,
            report: Some(report),
            flags: &Default::default(),
        }
        .run()
    }

    /// `robimu diagnose SESSION --out DIR` (noise model auto).
    fn diagnose(&self, session: &Path, out: &Path) -> anyhow::Result<Diagnosis> {
        let settings = robimu_workflows::DiagnoseSettings::new(out.to_path_buf());
        crate::flows::diagnose::run(session, &settings)
    }

    /// Plans the excitation, writes PLAN_DIR/plan.csv and says so.
    fn plan(&self, robot: &Robot, plan_dir: &Path) -> anyhow::Result<Plan> {
        let progress = Progress::start("planning");
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
        print!("{}", robimu_report::recording::imu_lines(&summary));
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
}

/// What to do after the demo: the verdict's first step when it is not
/// good, else export the calibrated robot.
fn next_step(fitted: &Fitted, session: &Path) -> String {
    let steps = fitted
        .result
        .verdict
        .as_ref()
        .map(|v| v.next_steps.as_slice());
    match steps.and_then(|s| s.first()) {
        Some(step) => step.clone(),
        None => format!(
            "robimu export --calibration {} --format toml --out robot.toml (the calibrated robot), then calibrate your own robot: docs/guide/getting-started.md",
            session.join("result.json").display()
        ),
    }
}

/// Prints the truth check and writes it into REPORT/truth_check.json and .txt.
fn write_check(out: &mut impl Write, check: &DemoTruthCheck, report: &Path) -> anyhow::Result<()> {
    write!(out, "{check}")?;
    std::fs::create_dir_all(report)
        .with_context(|| format!("cannot create {}", report.display()))?;
    let path = report.join("truth_check.json");
    std::fs::write(&path, serde_json::to_string_pretty(&check.to_json())?)
        .with_context(|| format!("cannot write {}", path.display()))?;
    let text = report.join("truth_check.txt");
    std::fs::write(&text, check.to_string())
        .with_context(|| format!("cannot write {}", text.display()))?;
    writeln!(out, "wrote {} and {}", path.display(), text.display())?;
    Ok(())
}
