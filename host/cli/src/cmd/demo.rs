//! `robimu demo`: the main job on simulated hardware. A plan, a simulated
//! AUBO i5 on loopback TCP and a simulated IMU board on a pseudo-terminal
//! (the real firmware core over a register-level BNO055 whose readings come
//! from the model at a hidden truth), a recording through the same code as
//! `robimu record`, and a calibration checked against the hidden truth.

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context};
use robimu_hil::rig::{SimRig, SimRigConfig};
use robimu_model::Robot;
use robimu_protocol::SensorConfig;
use robimu_record::controller::RobotSpec;
use robimu_record::motion::Plan;
use robimu_record::RecordOptions;
use robimu_session::{files, Truth};
use robimu_workflows::plan::PlanOptions;

use super::calibrate::CalibrateCmd;
use super::record::{print_summary, record_with_progress};

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
        let progress = super::input::Progress::start("planning");
        let t0 = Instant::now();
        let planned = robimu_workflows::plan::plan(
            &robot,
            &PlanOptions {
                duration: self.duration,
                seed: self.seed,
                ..PlanOptions::default()
            },
            |b, nb, l| progress.set_message(format!("planning: block {b}/{nb}, λ_max ≈ {l:.3e}")),
        )
        .context("cannot plan the excitation trajectory")?;
        progress.finish();
        let plan = Plan::from_spline(&planned.spline, 250.0);
        let plan_csv = plan_dir.join("plan.csv");
        plan.write_csv(&plan_csv)
            .with_context(|| format!("cannot write {}", plan_csv.display()))?;
        writeln!(
            out,
            "{} s excitation planned in {:.1} s (sequential, min λ_max(Σ_x) = {:.3e} in SI; exact joint limits; at rest at both ends): {} ({} waypoints at 250 Hz)",
            self.duration,
            t0.elapsed().as_secs_f64(),
            planned.lambda_max.last().copied().unwrap_or(f64::NAN),
            plan_csv.display(),
            plan.q.len()
        )?;

        writeln!(out, "\n== 2. simulated hardware ==")?;
        let mut config = SimRigConfig::drawn(robot.clone(), self.seed);
        config.clock_drift_ppm = self.drift_ppm;
        // The arm waits at the plan's first pose (a real one is moved there
        // first: `record` does that at half the slowest joint's limits).
        config.initial = plan.q[0];
        let rig = SimRig::spawn(&config).context("cannot start the simulated hardware")?;
        writeln!(
            out,
            "IMU board on {} (the real firmware core over a register-level BNO055; clock {:+.1} ppm)",
            rig.imu_port(),
            self.drift_ppm
        )?;
        writeln!(
            out,
            "AUBO i5 controller on {} (JSON-RPC, 20 ms tracking lag, encoder noise as the paper's)",
            rig.robot_addr()
        )?;
        writeln!(
            out,
            "hidden truth: robot errors and IMU parameters drawn from the priors (seed {})",
            self.seed
        )?;

        writeln!(out, "\n== 3. record ==")?;
        writeln!(
            out,
            "robimu record --imu {} --robot {} --plan {} --out {}",
            rig.imu_port(),
            rig.robot_spec(),
            plan_dir.display(),
            session.display()
        )?;
        let opts = RecordOptions {
            imu_port: rig.imu_port().to_string(),
            baud: 921_600,
            robot_spec: RobotSpec::parse(&rig.robot_spec())?,
            robot: robot.clone(),
            robot_name: "aubo_i5".into(),
            plan: Some(plan),
            duration: self.duration,
            out: session.clone(),
            joint_rate: 125.0,
            rest: 1.0,
            sensor: SensorConfig::default(),
            interrupt: None,
        };
        let summary = record_with_progress(&opts)?;
        print_summary(&summary);
        write_truth(&session, rig.truth())?;
        drop(rig);

        writeln!(out, "\n== 4. calibrate ==")?;
        out.flush()?;
        let t0 = Instant::now();
        CalibrateCmd {
            session: session.clone(),
            out: None,
            freeze: Vec::new(),
            no_prior: false,
            knot_spacing: None,
            noise: None,
            windows: None,
            report: Some(dir.join("report")),
            effects: Vec::new(),
            resonance: Default::default(),
        }
        .run()?;
        writeln!(out, "calibration took {:.1} s", t0.elapsed().as_secs_f64())?;
        writeln!(
            out,
            "\nfiles: {} (plan.csv), {} (session.toml, joints.csv, imu.csv, pings.csv, truth.toml = the hidden truth, result.json)",
            plan_dir.display(),
            session.display()
        )?;
        writeln!(
            out,
            "report: {} (open it in a browser; the figures are beside it as PNG and SVG)",
            dir.join("report").join("report.html").display()
        )?;
        writeln!(
            out,
            "demo took {:.1} s; next: robimu calibrate {} --freeze lengths",
            start.elapsed().as_secs_f64(),
            session.display()
        )?;
        Ok(())
    }
}

fn write_truth(session: &std::path::Path, truth: &Truth) -> anyhow::Result<()> {
    let path = session.join(files::TRUTH);
    std::fs::write(&path, truth.to_toml())
        .with_context(|| format!("cannot write {}", path.display()))
}
