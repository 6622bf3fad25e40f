//! A pose session's mount priors (`[imu.mount]`, `[imu<j>.mount]`,
//! docs/model.md §7.9, §9) over MODEL.md §10's: p_imu's prior mean and σ,
//! the sensor rotations' prior means and σ. A key IMU j ≥ 1 does not give
//! is IMU 0's, one IMU 0 does not give §10's (p_imu 0 ± 0.2 m; the
//! rotations found from the data with σ = π). Given rotation means with no
//! `rotation_sigma` take [`ROTATION_SIGMA`].

use std::f64::consts::PI;

use robimu_model::params::ParamSpec;
use robimu_model::pose_measurement::{ACCEL, GYRO, POSE_PARAMS, ROT};
use robimu_session::MountPrior;

/// The σ (rad) of given rotation means without `rotation_sigma`: a robot
/// description's default `[imu_mount]` σ, 5°.
pub(crate) const ROTATION_SIGMA: f64 = 5.0 * PI / 180.0;

/// Put `mount` into one IMU's §10 30-vector of `specs` (prior means and σ)
/// and `x0` (its start): p_imu's mean and σ where given; a given rotation's
/// mean with `rotation_sigma` (or [`ROTATION_SIGMA`]), the start's rotation
/// taken to its ZYX angles nearest that mean ([`nearest_zyx`]).
pub(crate) fn apply(mount: &MountPrior, specs: &mut [ParamSpec], x0: &mut [f64]) {
    debug_assert!(specs.len() == POSE_PARAMS && x0.len() == POSE_PARAMS);
    for k in 0..3 {
        if let Some(p) = mount.position {
            specs[k].nominal = p[k];
        }
        if let Some(s) = mount.position_sigma {
            specs[k].sigma = s;
        }
    }
    for (block, mean) in [(ACCEL, mount.r_a), (GYRO, mount.r_w)] {
        let Some(mean) = mean else { continue };
        let r = block + ROT..block + ROT + 3;
        let start: [f64; 3] = std::array::from_fn(|k| x0[r.start + k]);
        x0[r.clone()].copy_from_slice(&nearest_zyx(start, mean));
        for (k, spec) in specs[r].iter_mut().enumerate() {
            spec.nominal = mean[k];
            spec.sigma = mount.rotation_sigma.unwrap_or(ROTATION_SIGMA);
        }
    }
}

/// The ZYX angles (z, y, x) of the rotation `angles` name that are nearest
/// `mean`: of its two sets, (z, y, x) and (z + π, π − y, x + π), each angle
/// moved by whole turns towards `mean`'s, the one closer to `mean`.
pub(crate) fn nearest_zyx(angles: [f64; 3], mean: [f64; 3]) -> [f64; 3] {
    let [z, y, x] = angles;
    let turns = |a: [f64; 3]| -> [f64; 3] {
        std::array::from_fn(|k| a[k] - 2.0 * PI * ((a[k] - mean[k]) / (2.0 * PI)).round())
    };
    let distance = |a: &[f64; 3]| (0..3).map(|k| (a[k] - mean[k]).powi(2)).sum::<f64>();
    let (one, other) = (turns([z, y, x]), turns([z + PI, PI - y, x + PI]));
    if distance(&other) < distance(&one) {
        other
    } else {
        one
    }
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use super::*;
    use robimu_model::imu::ImuIntrinsics;

    fn rotation(a: [f64; 3]) -> robimu_model::geom::M3 {
        ImuIntrinsics::ideal(a).rotation()
    }

    #[test]
    fn nearest_zyx_is_the_same_rotation_near_the_mean() {
        for (angles, mean) in [
            ([3.1, 0.2, -3.0], [-3.1, 0.2, 3.1]),
            ([0.3, 1.2, 0.5], [0.3 + PI, PI - 1.2, 0.5 - PI]),
            ([0.1, -0.2, 0.3], [0.1, -0.2, 0.3 + 4.0 * PI]),
        ] {
            let near = nearest_zyx(angles, mean);
            let (a, b) = (rotation(angles), rotation(near));
            for r in 0..3 {
                for c in 0..3 {
                    assert!((a[r][c] - b[r][c]).abs() < 1e-12, "{angles:?} → {near:?}");
                }
            }
            for k in 0..3 {
                assert!(
                    (near[k] - mean[k]).abs() < 0.2,
                    "{near:?} not near {mean:?}"
                );
            }
        }
    }

    #[test]
    fn imu_j_keeps_imu_0_keys_it_does_not_give() {
        let m0 = MountPrior {
            position: Some([0.1, 0.0, 0.0]),
            r_a: Some([1.0, 0.0, 0.0]),
            ..Default::default()
        };
        let m2 = MountPrior {
            position: Some([0.2, 0.0, 0.0]),
            position_sigma: Some(0.01),
            ..Default::default()
        };
        let mounts = BTreeMap::from([(0, m0), (2, m2)]);
        assert_eq!(MountPrior::of_imu(&mounts, 0), m0);
        assert_eq!(MountPrior::of_imu(&mounts, 1), m0);
        let two = MountPrior::of_imu(&mounts, 2);
        assert_eq!(two.position, Some([0.2, 0.0, 0.0]));
        assert_eq!(two.r_a, Some([1.0, 0.0, 0.0]));
        assert_eq!(
            MountPrior::of_imu(&BTreeMap::new(), 3),
            MountPrior::default()
        );

        let mut specs = robimu_model::pose_measurement::pose_param_specs([0.0; 3], [0.0; 3]);
        let mut x0 = vec![0.0; POSE_PARAMS];
        x0[ACCEL + ROT] = 1.0 - 2.0 * PI;
        apply(&two, &mut specs, &mut x0);
        assert_eq!((specs[0].nominal, specs[0].sigma), (0.2, 0.01));
        assert_eq!((specs[1].nominal, specs[1].sigma), (0.0, 0.01));
        let r = ACCEL + ROT;
        assert_eq!((specs[r].nominal, specs[r].sigma), (1.0, ROTATION_SIGMA));
        assert!((x0[r] - 1.0).abs() < 1e-12, "start {}", x0[r]);
        // the gyroscope's rotation: no mean given, §10's σ = π
        assert_eq!(specs[GYRO + ROT].sigma, PI);
    }
}
