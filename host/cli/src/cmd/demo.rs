//! `robimu demo`: the main job on simulated hardware. A plan, a simulated
//! AUBO i5 on loopback TCP and a simulated IMU board on a pseudo-terminal
//! (the real firmware core over a register-level BNO055 whose readings come
//! from the model at a hidden truth), a recording through the same code as
//! `robimu record`, and a calibration checked against the hidden truth.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context};
use robimu_hil::rig::{SimRig, SimRigConfig};
use robimu_model::Robot;
use robimu_protocol::SensorConfig;
use robimu_record::controller::RobotSpec;
use robimu_record::motion::Plan;
use robimu_record::RecordOptions;
use robimu_report::demo::{DemoFiles, DemoHardware, DemoPlanned, DemoRecordCommand};
use robimu_session::files;
use robimu_workflows::plan::PlanOptions;

use super::calibrate::CalibrateCmd;
use super::input::record_with_progress;
use robimu_report::recording::RecordSummaryText;

/// Run the main job on simulated hardware, no robot or IMU needed: plan,
/// record from a simulated AUBO i5 and IMU board with a hidden truth,
/// calibrate, and compare with the truth.
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
}

impl DemoCmd {
    /// Plan, record, calibrate.
    pub fn run(self) -> anyhow::Result<()> {
        let start = Instant::now();
        if !(self.duration.is_finite() && (5.0..=3600.0).contains(&self.duration)) {
            bail!("--duration must be in [5, 3600] s (got {})", self.duration);
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
        let rig = self.hardware(&robot, &plan)?;

        writeln!(out, "\n== 3. record ==")?;
        let (plan_dir, session) = (plan_dir.as_path(), session.as_path());
        self.record(&rig, robot, plan, plan_dir, session)?;
        drop(rig);

        writeln!(out, "\n== 4. calibrate ==")?;
        out.flush()?;
        let t0 = Instant::now();
        let report = dir.join("report");
        self.calibrate(session, &report)?;
        writeln!(out, "calibration took {:.1} s", t0.elapsed().as_secs_f64())?;
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

    /// Starts the simulated board and AUBO controller, the arm at the
    /// plan's first pose, and says so.
    fn hardware(&self, robot: &Robot, plan: &Plan) -> anyhow::Result<SimRig> {
        let mut config = SimRigConfig::drawn(robot.clone(), self.seed);
        config.clock_drift_ppm = self.drift_ppm;
        // The arm waits at the plan's first pose (a real one is moved there
        // first: `record` does that at half the slowest joint's limits).
        config.initial = plan.q[0];
        let rig = SimRig::spawn(&config).context("cannot start the simulated hardware")?;
        let hardware = DemoHardware {
            imu_port: rig.imu_port(),
            drift_ppm: self.drift_ppm,
            robot_addr: rig.robot_addr().to_string(),
            seed: self.seed,
        };
        write!(std::io::stdout(), "{hardware}")?;
        Ok(rig)
    }

    /// Records the plan from `rig` into `session` as `robimu record` does,
    /// with the hidden truth beside it.
    fn record(
        &self,
        rig: &SimRig,
        robot: Robot,
        plan: Plan,
        plan_dir: &Path,
        session: &Path,
    ) -> anyhow::Result<()> {
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
            baud: 921_600,
            robot_spec: RobotSpec::parse(&robot_spec)?,
            robot,
            robot_name: "aubo_i5".into(),
            plan: Some(plan),
            duration: self.duration,
            out: session.to_path_buf(),
            joint_rate: 125.0,
            rest: 1.0,
            sensor: SensorConfig::default(),
            interrupt: None,
        };
        let summary = record_with_progress(&opts)?;
        print!("{}", RecordSummaryText(&summary));
        let truth = session.join(files::TRUTH);
        std::fs::write(&truth, rig.truth().to_toml())
            .with_context(|| format!("cannot write {}", truth.display()))
    }

    /// `robimu calibrate SESSION --report REPORT`.
    fn calibrate(&self, session: &Path, report: &Path) -> anyhow::Result<()> {
        CalibrateCmd {
            session: session.to_path_buf(),
            out: None,
            freeze: Vec::new(),
            no_prior: false,
            knot_spacing: None,
            noise: None,
            windows: None,
            report: Some(report.to_path_buf()),
            effects: Vec::new(),
            resonance: Default::default(),
            noise_model: "auto".into(),
            noise_refits: robimu_workflows::calibrate::noise_choice::MAX_REFITS,
            noise_settle: None,
        }
        .run()
    }
}
