//! A calibration in the formats other tools read: the corrected robot as a
//! URDF or robot TOML ([`robot`]) or Universal Robots' kinematics YAML
//! ([`ur`], which also reads a factory calibration; [`ur_conf`] the
//! controller's own `calibration.conf`), the IMU intrinsics as a Kalibr `imu.yaml`
//! or a correction file for firmware and drivers, and the inverse sensor
//! model applied to a raw IMU CSV ([`imu`]).
//!
//! Everything starts from the estimated parameters of a `result.json`
//! (docs/model.md §8) for a robot: [`calibrated_params`].

pub mod imu;
pub mod robot;
pub mod ros2_control;
pub mod ur;
pub mod ur_conf;

use crate::result::CalibrationResult;
use robimu_model::{ImuIntrinsics, ModelParams, ParamLayout, Robot};

/// Why an export could not be made.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// A parameter the export needs is not in the result.
    #[error("the calibration result has no parameter `{0}`")]
    MissingParameter(String),
    /// The result names a generalized error the robot does not have.
    #[error("the calibration result has `{name}` but the robot has {n} joints")]
    WrongRobot {
        /// Parameter name.
        name: String,
        /// The robot's joints.
        n: usize,
    },
    /// A sensor matrix cannot be inverted.
    #[error("the {0} model matrix K·Γ·R is singular: it cannot be inverted")]
    Singular(&'static str),
    /// The URDF could not be read or rewritten.
    #[error(transparent)]
    Urdf(#[from] robimu_model::urdf::UrdfError),
    /// The TOML could not be written.
    #[error("cannot write TOML: {0}")]
    Toml(#[from] toml::ser::Error),
    /// An IMU table could not be read.
    #[error(transparent)]
    Session(#[from] crate::SessionError),
    /// An output file could not be written.
    #[error("cannot write {path}: {source}")]
    Write {
        /// The file.
        path: String,
        /// The cause.
        source: std::io::Error,
    },
}

/// The typed parameters of a calibration result for `robot`: every
/// parameter by its docs/model.md §5 name; generalized errors the result does not
/// list take the robot's fixed values (0, and the IMU mount position for
/// ε_n1..3), as in [`ParamLayout::unpack`].
pub fn calibrated_params(
    robot: &Robot,
    result: &CalibrationResult,
) -> Result<ModelParams, ExportError> {
    let n = robot.dof();
    let layout = ParamLayout::new(robot);
    let mut x = layout.nominal();
    for (k, spec) in layout.specs().iter().enumerate() {
        if let Some(p) = result.parameter(&spec.name) {
            x[k] = p.value;
        } else if !spec.name.starts_with("eps_") {
            return Err(ExportError::MissingParameter(spec.name.clone()));
        }
    }
    let mut params = layout
        .unpack(&x)
        .expect("x built from the layout has its length");
    // ε the result estimated but this robot's layout does not: set directly.
    for p in &result.parameters {
        let Some(rest) = p.name.strip_prefix("eps_") else {
            continue;
        };
        let mut it = rest.split('_').map(|s| s.parse::<usize>());
        let (Some(Ok(link)), Some(Ok(k)), None) = (it.next(), it.next(), it.next()) else {
            continue;
        };
        if link == 0 || link > n || !(1..=6).contains(&k) {
            return Err(ExportError::WrongRobot {
                name: p.name.clone(),
                n,
            });
        }
        params.eps[link - 1][k - 1] = p.value;
    }
    Ok(params)
}

/// The accelerometer and gyroscope intrinsics of a calibration result, by
/// their docs/model.md §5 names (no robot needed).
pub fn calibrated_intrinsics(
    result: &CalibrationResult,
) -> Result<(ImuIntrinsics, ImuIntrinsics), ExportError> {
    let get = |name: String| {
        result
            .parameter(&name)
            .map(|p| p.value)
            .ok_or(ExportError::MissingParameter(name))
    };
    let sensor = |s: &str| -> Result<ImuIntrinsics, ExportError> {
        let v3 = |prefix: &str, axes: [&str; 3]| -> Result<[f64; 3], ExportError> {
            Ok([
                get(format!("{prefix}_{s}_{}", axes[0]))?,
                get(format!("{prefix}_{s}_{}", axes[1]))?,
                get(format!("{prefix}_{s}_{}", axes[2]))?,
            ])
        };
        Ok(ImuIntrinsics {
            gamma: v3("gamma", ["yz", "zy", "zx"])?,
            r: v3("r", ["z", "y", "x"])?,
            k: v3("k", ["x", "y", "z"])?,
            b: v3("b", ["x", "y", "z"])?,
        })
    };
    Ok((sensor("a")?, sensor("w")?))
}

/// The fitted `g_sensitivity` G and `size_effect` lever arms r_y, r_z of a
/// calibration result (docs/model.md §4.5), `None` for an effect it did not
/// fit; an effect with only some of its parameters is an error.
#[allow(clippy::type_complexity)]
pub fn imu_effects(
    result: &CalibrationResult,
) -> Result<(Option<[[f64; 3]; 3]>, Option<[[f64; 3]; 2]>), ExportError> {
    let axes = ['x', 'y', 'z'];
    let effect = |names: Vec<String>| -> Result<Option<Vec<f64>>, ExportError> {
        let values: Vec<Option<f64>> = names
            .iter()
            .map(|n| result.parameter(n).map(|p| p.value))
            .collect();
        if values.iter().all(Option::is_none) {
            return Ok(None);
        }
        values
            .iter()
            .zip(&names)
            .map(|(v, n)| v.ok_or_else(|| ExportError::MissingParameter(n.clone())))
            .collect::<Result<Vec<f64>, _>>()
            .map(Some)
    };
    let g = effect(
        axes.iter()
            .flat_map(|r| axes.iter().map(move |c| format!("g_sensitivity.g{r}_s{c}")))
            .collect(),
    )?
    .map(|v| std::array::from_fn(|r| std::array::from_fn(|c| v[3 * r + c])));
    let size = effect(
        ['y', 'z']
            .iter()
            .flat_map(|a| axes.iter().map(move |c| format!("size_effect.r{a}_{c}")))
            .collect(),
    )?
    .map(|v| std::array::from_fn(|a| std::array::from_fn(|c| v[3 * a + c])));
    Ok((g, size))
}
