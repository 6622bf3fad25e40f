//! Reading a plan directory (what `robimu plan` writes): `plan.csv`, the
//! samples `t,q1,…,qn` (s, rad) a controller executes, and `spline.toml`,
//! the planned spline itself ([`SplineFile`]).

use std::path::{Path, PathBuf};

use robimu_model::trajectory::from_samples;
use robimu_model::{Robot, Spline, SplineError};
use robimu_session::{read_table, Columns, SessionError, Table};

use super::SplineFile;

/// Why a plan directory could not be used.
#[derive(Debug, thiserror::Error)]
pub enum PlanFileError {
    /// plan.csv is not a readable table.
    #[error(transparent)]
    Table(#[from] SessionError),
    /// spline.toml could not be read.
    #[error("cannot read {}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// spline.toml is not a spline file.
    #[error("{}: not a spline file", path.display())]
    NotSplineFile {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: toml::de::Error,
    },
    /// spline.toml does not describe a valid spline.
    #[error("{}: not a valid spline", path.display())]
    InvalidSpline {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: SplineError,
    },
    /// The directory holds no plan.
    #[error("{}: no spline.toml or plan.csv (write one with `robimu plan --out {}`)", dir.display(), dir.display())]
    NoPlan {
        /// The directory.
        dir: PathBuf,
    },
    /// The samples of plan.csv cannot be fitted by a trajectory.
    #[error("{}: {what}", path.display())]
    Unrepresentable {
        /// plan.csv.
        path: PathBuf,
        /// What could not be done.
        what: &'static str,
        /// Why.
        #[source]
        source: SplineError,
    },
    /// The plan's trajectory has another joint count than the robot.
    #[error("{}: the plan has {found} joints but robot `{robot}` has {expected}", dir.display())]
    Joints {
        /// The directory.
        dir: PathBuf,
        /// The plan's joints.
        found: usize,
        /// The robot.
        robot: String,
        /// The robot's joints.
        expected: usize,
    },
    /// plan.csv has another joint count than the robot.
    #[error("{}: {found} joint columns, but robot `{robot}` has {expected} joints", path.display())]
    Columns {
        /// plan.csv.
        path: PathBuf,
        /// Its joint columns.
        found: usize,
        /// The robot.
        robot: String,
        /// The robot's joints.
        expected: usize,
    },
    /// A sample is outside a joint's position limits.
    #[error("{}: row {row} (t = {t} s): q{joint} = {q} rad is outside the joint limits [{min}, {max}]", path.display())]
    OutsideLimits {
        /// plan.csv.
        path: PathBuf,
        /// 1-based row.
        row: usize,
        /// Its time, s.
        t: f64,
        /// 1-based joint.
        joint: usize,
        /// The position, rad.
        q: f64,
        /// The lower limit, rad.
        min: f64,
        /// The upper limit, rad.
        max: f64,
    },
    /// plan.csv has too few samples.
    #[error("{}: a plan needs at least 8 samples, found {found}", path.display())]
    TooShort {
        /// plan.csv.
        path: PathBuf,
        /// Its samples.
        found: usize,
    },
}

/// The samples of `dir/plan.csv`, checked against the robot's joint count
/// and position limits.
pub fn read_plan_table(robot: &Robot, dir: &Path) -> Result<Table, PlanFileError> {
    let path = dir.join("plan.csv");
    let table = read_table(&path, Columns::Joints)?;
    let n = robot.dof();
    if table.width() != n {
        return Err(PlanFileError::Columns {
            path,
            found: table.width(),
            robot: robot.name().to_string(),
            expected: n,
        });
    }
    for (s, row) in table.values.chunks_exact(n).enumerate() {
        for (j, (q, lim)) in row.iter().zip(robot.limits()).enumerate() {
            if *q < lim.q_min - 1e-9 || *q > lim.q_max + 1e-9 {
                return Err(PlanFileError::OutsideLimits {
                    path,
                    row: s + 1,
                    t: table.t[s],
                    joint: j + 1,
                    q: *q,
                    min: lim.q_min,
                    max: lim.q_max,
                });
            }
        }
    }
    if table.len() < 8 {
        return Err(PlanFileError::TooShort {
            path,
            found: table.len(),
        });
    }
    Ok(table)
}

/// The trajectory of `dir/plan.csv` ([`read_plan_table`]).
pub(crate) fn read_plan(robot: &Robot, dir: &Path) -> Result<Spline, PlanFileError> {
    let table = read_plan_table(robot, dir)?;
    from_samples(robot.dof(), &table.t, &table.values).map_err(|source| {
        PlanFileError::Unrepresentable {
            path: dir.join("plan.csv"),
            what: "cannot represent the plan as a trajectory",
            source,
        }
    })
}

/// The plan's trajectory: `dir/spline.toml` if present, else
/// `dir/plan.csv` refitted; its joint count checked against the robot's.
pub fn read_plan_spline(robot: &Robot, dir: &Path) -> Result<Spline, PlanFileError> {
    let path = dir.join("spline.toml");
    let spline = if path.is_file() {
        let text =
            robimu_model::text::read_to_string(&path).map_err(|source| PlanFileError::Read {
                path: path.clone(),
                source,
            })?;
        let file: SplineFile =
            toml::from_str(&text).map_err(|source| PlanFileError::NotSplineFile {
                path: path.clone(),
                source,
            })?;
        file.spline()
            .map_err(|source| PlanFileError::InvalidSpline { path, source })?
    } else {
        let path = dir.join("plan.csv");
        if !path.is_file() {
            return Err(PlanFileError::NoPlan {
                dir: dir.to_path_buf(),
            });
        }
        let table = read_table(&path, Columns::Joints)?;
        from_samples(table.width(), &table.t, &table.values).map_err(|source| {
            PlanFileError::Unrepresentable {
                path,
                what: "cannot represent the plan",
                source,
            }
        })?
    };
    if spline.dim() != robot.dof() {
        return Err(PlanFileError::Joints {
            dir: dir.to_path_buf(),
            found: spline.dim(),
            robot: robot.name().to_string(),
            expected: robot.dof(),
        });
    }
    Ok(spline)
}
