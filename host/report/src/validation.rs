//! What `robimu validate` prints and writes besides validation.html: the
//! robot and IMU accuracy tables and validation.json, the numbers of the
//! tables (SI units and mm/deg).

use std::fmt;
use std::path::{Path, PathBuf};

use robimu_workflows::tracker_offset::TrackerAlignment;
use robimu_workflows::validate::{ImuAccuracy, ImuErrors, PoseErrors, RobotAccuracy};
use serde_json::{json, Value};

use crate::html::ReportError;

/// The robot accuracy on the held-out poses (paper Fig. 10), as a table.
pub struct RobotAccuracyTable<'a>(pub &'a RobotAccuracy);

impl fmt::Display for RobotAccuracyTable<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let acc = self.0;
        writeln!(
            f,
            "robot accuracy on {} held-out poses ({} fit the transforms and the classical calibration):",
            acc.test, acc.train
        )?;
        writeln!(
            f,
            "{:<26} {:>12} {:>10} {:>12} {:>10}",
            "parameters", "mean [mm]", "max [mm]", "mean [deg]", "max [deg]"
        )?;
        for (name, e) in [
            ("nominal", &acc.nominal),
            ("calibrated", &acc.calibrated),
            ("classical (tracker)", &acc.classical),
        ] {
            writeln!(
                f,
                "{:<26} {:>12.3} {:>10.3} {:>12.4} {:>10.4}",
                name,
                1e3 * e.mean_position(),
                1e3 * e.max_position(),
                e.mean_rotation().to_degrees(),
                e.max_rotation().to_degrees()
            )?;
        }
        Ok(())
    }
}

/// The IMU accuracy on the held-out samples (paper Fig. 11), as a table.
pub struct ImuAccuracyTable<'a>(pub &'a ImuAccuracy);

impl fmt::Display for ImuAccuracyTable<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let imu = self.0;
        writeln!(
            f,
            "IMU accuracy on {} held-out samples ({} fit the classical IMU calibration):",
            imu.test, imu.train
        )?;
        writeln!(
            f,
            "{:<26} {:>16} {:>18}",
            "intrinsics", "rms |dw| [deg/s]", "rms |ds| [m/s^2]"
        )?;
        for (name, e) in [
            ("nominal", &imu.nominal),
            ("calibrated", &imu.calibrated),
            ("classical (tracker)", &imu.classical),
        ] {
            writeln!(
                f,
                "{:<26} {:>16.3} {:>18.3}",
                name,
                e.rms_gyro().to_degrees(),
                e.rms_accel()
            )?;
        }
        Ok(())
    }
}

/// validation.json's contents.
pub(crate) fn validation_json(
    acc: &RobotAccuracy,
    imu: Option<&ImuAccuracy>,
    alignment: Option<&TrackerAlignment>,
) -> Value {
    let pose = |e: &PoseErrors| {
        json!({
            "mean_position_mm": 1e3 * e.mean_position(),
            "max_position_mm": 1e3 * e.max_position(),
            "mean_rotation_deg": e.mean_rotation().to_degrees(),
            "max_rotation_deg": e.max_rotation().to_degrees(),
        })
    };
    let mut v = json!({
        "robot_accuracy": {
            "train": acc.train,
            "test": acc.test,
            "nominal": pose(&acc.nominal),
            "calibrated": pose(&acc.calibrated),
            "classical": pose(&acc.classical),
        },
    });
    if let Some(imu) = imu {
        let errs = |e: &ImuErrors| {
            json!({
                "rms_gyro_deg_s": e.rms_gyro().to_degrees(),
                "rms_accel_m_s2": e.rms_accel(),
            })
        };
        v["imu_accuracy"] = json!({
            "train": imu.train,
            "test": imu.test,
            "nominal": errs(&imu.nominal),
            "calibrated": errs(&imu.calibrated),
            "classical": errs(&imu.classical),
        });
    }
    if let Some(a) = alignment {
        v["tracker_offset"] = json!({
            "delta_s": a.delta,
            "delta_ms": 1e3 * a.delta,
            "estimated": a.estimate.is_some(),
            "r_squared": a.estimate.map(|e| e.r_squared),
            "rms_deg_s": a.estimate.map(|e| e.rms.to_degrees()),
            "overlap_s": a.estimate.map(|e| e.overlap),
        });
    }
    v
}

/// Writes `dir/validation.json` ([`validation_json`], pretty-printed);
/// returns its path.
pub fn write_validation_json(
    dir: &Path,
    acc: &RobotAccuracy,
    imu: Option<&ImuAccuracy>,
    alignment: Option<&TrackerAlignment>,
) -> Result<PathBuf, ReportError> {
    let path = dir.join("validation.json");
    let json = validation_json(acc, imu, alignment);
    std::fs::write(&path, format!("{json:#}\n")).map_err(|source| ReportError::Io {
        path: path.clone(),
        source,
    })?;
    Ok(path)
}
