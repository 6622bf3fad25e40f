//! `robimu repair`: make a recording cut short by a crash whole again.

use std::path::PathBuf;

use anyhow::Context;
use robimu_record::repair::repair;
use robimu_report::recording::RepairText;
use robimu_session::Session;

/// Repair a recorded session: drop a cut last line from each file,
/// recompute the IMU times from the ping log and (UR) the joint times from
/// the controller's timestamps.
#[derive(Debug, Clone, clap::Args)]
pub struct RepairCmd {
    /// The session directory.
    pub session: PathBuf,
}

impl RepairCmd {
    /// Repair, then load the session to check it.
    pub fn run(self) -> anyhow::Result<()> {
        let report = repair(&self.session)
            .with_context(|| format!("cannot repair {}", self.session.display()))?;
        print!("{}", RepairText(&report));
        let session = Session::load(&self.session).with_context(|| {
            format!("{} is still not a readable session", self.session.display())
        })?;
        let m = session.measurements();
        println!(
            "{} is readable: {} joint and {} IMU samples",
            self.session.display(),
            m.joint_t.len(),
            m.imu_t.len()
        );
        Ok(())
    }
}
