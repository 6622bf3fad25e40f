//! The text of `robimu demo` between its stages: what was planned, the
//! simulated hardware, the equivalent `robimu record` command, the files.

use std::fmt;
use std::path::Path;

/// The plan stage: the excitation planned and written.
pub struct DemoPlanned<'a> {
    /// Length of the excitation, s.
    pub duration: f64,
    /// How long planning took, s.
    pub seconds: f64,
    /// The final min λ_max(Σ_x), SI.
    pub lambda_max: f64,
    /// plan.csv.
    pub path: &'a Path,
    /// Its waypoints (at 250 Hz).
    pub waypoints: usize,
}

impl fmt::Display for DemoPlanned<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{} s excitation planned in {:.1} s (sequential, min λ_max(Σ_x) = {:.3e} in SI; exact joint limits; at rest at both ends): {} ({} waypoints at 250 Hz)",
            self.duration,
            self.seconds,
            self.lambda_max,
            self.path.display(),
            self.waypoints
        )
    }
}

/// The simulated hardware stage.
pub struct DemoHardware<'a> {
    /// The IMU board's pseudo-terminal.
    pub imu_port: &'a str,
    /// The board's clock drift, ppm.
    pub drift_ppm: f64,
    /// The AUBO controller's address.
    pub robot_addr: String,
    /// The seed of the hidden truth.
    pub seed: u64,
}

impl fmt::Display for DemoHardware<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "IMU board on {} (the real firmware core over a register-level BNO055; clock {:+.1} ppm)",
            self.imu_port, self.drift_ppm
        )?;
        writeln!(
            f,
            "AUBO i5 controller on {} (JSON-RPC, 20 ms tracking lag, encoder noise as the paper's)",
            self.robot_addr
        )?;
        writeln!(
            f,
            "hidden truth: robot errors and IMU parameters drawn from the priors (seed {})",
            self.seed
        )
    }
}

/// The `robimu record` command the record stage runs.
pub struct DemoRecordCommand<'a> {
    /// --imu.
    pub imu_port: &'a str,
    /// --robot.
    pub robot_spec: &'a str,
    /// --plan.
    pub plan_dir: &'a Path,
    /// --out.
    pub session: &'a Path,
}

impl fmt::Display for DemoRecordCommand<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "robimu record --imu {} --robot {} --plan {} --out {}",
            self.imu_port,
            self.robot_spec,
            self.plan_dir.display(),
            self.session.display()
        )
    }
}

/// Where the demo left its files, and what to try next.
pub struct DemoFiles<'a> {
    /// The plan directory.
    pub plan_dir: &'a Path,
    /// The session directory.
    pub session: &'a Path,
    /// The report directory.
    pub report: &'a Path,
    /// How long the demo took, s.
    pub seconds: f64,
}

impl fmt::Display for DemoFiles<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "\nfiles: {} (plan.csv), {} (session.toml, joints.csv, imu.csv, pings.csv, truth.toml = the hidden truth, result.json)",
            self.plan_dir.display(),
            self.session.display()
        )?;
        writeln!(
            f,
            "report: {} (open it in a browser; the figures are beside it as PNG and SVG)",
            self.report.join("report.html").display()
        )?;
        writeln!(
            f,
            "demo took {:.1} s; next: robimu calibrate {} --freeze lengths",
            self.seconds,
            self.session.display()
        )
    }
}
