//! `robimu correct`: the inverse sensor model applied to a raw IMU CSV.

use std::path::PathBuf;

use anyhow::{bail, Context};
use robimu_session::export::calibrated_intrinsics;
use robimu_session::export::imu::{correct_rows, write_imu_csv};
use robimu_session::result::CalibrationResult;
use robimu_session::{read_table, Columns, IMU_COLUMNS};

use crate::input::output_path;

/// Correct a raw IMU recording with a calibration: per sample and sensor
/// v = Rᵀ·Γ⁻¹·K⁻¹·(z − b) (the inverse of docs/model.md §3), the specific force
/// (m/s²) and angular rate (rad/s) in the IMU frame (axes of the flange).
///
/// Input and output are imu.csv files (header `t,ax,ay,az,gx,gy,gz`, SI;
/// docs/model.md §7); extra input columns are dropped. With a result of
/// several IMUs (docs/model.md §9) the correction is IMU J's (`--imu J`;
/// without it, J from the input's name `imu.csv` / `imu<J>.csv`).
#[derive(Debug, Clone, clap::Args)]
pub struct CorrectCmd {
    /// The calibration result (result.json from `robimu calibrate`).
    #[arg(long)]
    pub calibration: PathBuf,
    /// The raw IMU CSV.
    pub imu: PathBuf,
    /// A result of several IMUs: correct with IMU J's parameters [default:
    /// J of an input named imu<J>.csv, 0 for imu.csv].
    #[arg(long = "imu", value_name = "J")]
    pub which_imu: Option<usize>,
    /// File to write [default: <IMU>_corrected.csv beside the input].
    #[arg(long)]
    pub out: Option<PathBuf>,
}

impl CorrectCmd {
    /// Read, correct, write.
    pub fn run(self) -> anyhow::Result<()> {
        let stem = self
            .imu
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "imu".into());
        let out = output_path(
            self.out.as_deref(),
            self.imu.with_file_name(format!("{stem}_corrected.csv")),
        )?;
        if out == self.imu {
            bail!("--out {}: would overwrite the input", out.display());
        }
        let result = CalibrationResult::read(&self.calibration)?;
        if let Some(note) = result.effects_not_carried("the sensor model's inverse") {
            eprintln!("note: {note}");
        }
        let k = result.imu_count();
        let j = match (self.which_imu, imu_of_file(&self.imu)) {
            (Some(j), _) => j,
            (None, _) if k == 1 => 0,
            (None, Some(j)) => j,
            (None, None) => bail!(
                "{} has {k} IMUs and {} is not named imu.csv or imu<J>.csv: give --imu J (0 to {})",
                self.calibration.display(),
                self.imu.display(),
                k - 1
            ),
        };
        let result = result
            .imu(j)
            .map_err(|e| anyhow::anyhow!("{}: {e}", self.calibration.display()))?;
        let (accel, gyro) = calibrated_intrinsics(&result)
            .with_context(|| format!("{}: no IMU parameters", self.calibration.display()))?;
        let table = read_table(&self.imu, Columns::Fixed(&IMU_COLUMNS))?;
        let rows: Vec<[f64; 6]> = (0..table.len())
            .map(|i| {
                let r = table.row(i);
                [r[0], r[1], r[2], r[3], r[4], r[5]]
            })
            .collect();
        let corrected = correct_rows(&accel, &gyro, &rows)?;
        write_imu_csv(&out, &table.t, &corrected)?;
        println!("wrote {} ({} samples)", out.display(), corrected.len());
        Ok(())
    }
}

/// J of an IMU file named `imu.csv` (0) or `imu<J>.csv` (docs/model.md §9).
fn imu_of_file(path: &std::path::Path) -> Option<usize> {
    let name = path.file_name()?.to_str()?;
    let digits = name.strip_prefix("imu")?.strip_suffix(".csv")?;
    if digits.is_empty() {
        return Some(0);
    }
    if digits.starts_with('0') {
        return None;
    }
    digits.parse().ok()
}
