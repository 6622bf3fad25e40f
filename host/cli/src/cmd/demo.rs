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

use crate::flows::demo::DemoArgs;

/// Run the main job on simulated hardware, no robot or IMU needed: plan,
/// record from a simulated AUBO i5 and IMU board with a hidden truth (the
/// realistic twin unless --ideal), calibrate, diagnose, and compare
/// diagnose's final model with the truth.
#[derive(Debug, Clone, clap::Args)]
pub struct DemoCmd {
    #[command(flatten)]
    pub demo: DemoArgs,
}

impl DemoCmd {
    /// Plan, record, calibrate, diagnose, check against the truth.
    pub fn run(self) -> anyhow::Result<()> {
        self.demo.run()
    }
}
