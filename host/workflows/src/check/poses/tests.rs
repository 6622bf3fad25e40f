//! Each pose-session finding fires on its fault and stays silent on a clean
//! session (a smooth motion, 100 Hz poses, 200 Hz IMU samples).

use super::*;
use robimu_session::{ImuTable, PoseSessionMeta, IMU_COLUMNS, POSE_COLUMNS};

fn table(columns: &[&str], t: Vec<f64>, values: Vec<f64>) -> Table {
    Table {
        columns: columns.iter().map(|c| c.to_string()).collect(),
        t,
        values,
    }
}

/// A pose on a slow curve: p(t) on a circle of 0.3 m, R(t) = Exp(0.4 t ·
/// axis) about a tilted axis.
fn pose(t: f64) -> [f64; 7] {
    let (s, c) = (0.5 * t).sin_cos();
    let axis = [0.6, 0.0, 0.8];
    let (h_s, h_c) = (0.5 * 0.4 * t).sin_cos();
    [
        0.5 + 0.3 * c,
        0.3 * s,
        0.4 + 0.05 * (0.3 * t).sin(),
        h_c,
        h_s * axis[0],
        h_s * axis[1],
        h_s * axis[2],
    ]
}

/// An IMU sample with every channel moving.
fn imu_row(t: f64) -> [f64; 6] {
    [
        0.3 * (1.1 * t).sin(),
        0.2 * (0.9 * t).cos(),
        9.81 + 0.1 * (0.7 * t).sin(),
        0.4 * (0.5 * t).cos(),
        0.1 * (0.8 * t).sin(),
        0.32 + 0.05 * (0.6 * t).sin(),
    ]
}

/// A clean session of `seconds`: poses at 100 Hz, IMU samples at 200 Hz.
fn clean(seconds: usize) -> PoseSession {
    let pt: Vec<f64> = (0..seconds * 100).map(|i| i as f64 * 0.01).collect();
    let pv = pt.iter().flat_map(|&t| pose(t)).collect();
    let it: Vec<f64> = (0..seconds * 200).map(|i| i as f64 * 0.005).collect();
    let iv = it.iter().flat_map(|&t| imu_row(t)).collect();
    PoseSession {
        dir: "mem".into(),
        meta: PoseSessionMeta::default(),
        poses: table(&POSE_COLUMNS, pt, pv),
        imus: vec![ImuTable {
            samples: table(&IMU_COLUMNS, it, iv),
            temp: None,
        }],
        truth: None,
    }
}

fn kinds(r: &CheckReport) -> Vec<&'static str> {
    r.findings.iter().map(|f| f.kind).collect()
}

#[track_caller]
fn only<'a>(r: &'a CheckReport, kind: &str) -> &'a Finding {
    let all: Vec<_> = r.findings.iter().filter(|f| f.kind == kind).collect();
    assert_eq!(all.len(), 1, "{:#?}", r.findings);
    all[0]
}

#[test]
fn a_clean_session_has_rates_and_overlap_only() {
    let r = check_pose_session(&clean(60));
    assert_eq!(kinds(&r), ["rate", "rate", "overlap"], "{:#?}", r.findings);
    assert!(r.findings.iter().all(|f| f.severity == Severity::Info));
    assert!((r.findings[0].value - 100.0).abs() < 1e-6);
    assert_eq!(r.findings[0].subject, "poses.csv");
    assert!((r.findings[1].value - 200.0).abs() < 1e-6);
    assert!((r.findings[2].value - 1.0).abs() < 1e-9);
}

#[test]
fn sign_flips_are_counted() {
    let mut s = clean(60);
    for i in (1000..1500).chain(3000..3001) {
        for k in 3..7 {
            s.poses.values[7 * i + k] *= -1.0;
        }
    }
    let r = check_pose_session(&s);
    let f = only(&r, "quaternion_sign");
    assert_eq!((f.value, f.severity), (4.0, Severity::Info));
    assert!(f.message.contains("first at t = 10.000 s"), "{}", f.message);
    assert!(r.fatal().is_none());
}

#[test]
fn non_unit_quaternions_are_counted_with_the_worst() {
    let mut s = clean(60);
    for (i, scale) in [(100, 1.01), (200, 0.9995), (300, 1.05), (400, 0.998)] {
        for k in 3..7 {
            s.poses.values[7 * i + k] *= scale;
        }
    }
    let r = check_pose_session(&s);
    let f = only(&r, "quaternion_norm");
    assert_eq!((f.value, f.severity), (3.0, Severity::Warning));
    assert!(
        f.message.contains("worst |q| = 1.050000 at t = 3.000 s"),
        "{}",
        f.message
    );
    // every quaternion twice its length: not unit quaternions at all
    for v in s.poses.values.chunks_exact_mut(7) {
        for x in &mut v[3..] {
            *x *= 2.0;
        }
    }
    let r = check_pose_session(&s);
    let f = only(&r, "quaternion_norm");
    assert_eq!((f.value, f.severity), (6000.0, Severity::Fatal));
}

#[test]
fn positions_in_mm_are_fatal_and_name_the_import_option() {
    let mut s = clean(60);
    for v in s.poses.values.chunks_exact_mut(7) {
        for x in &mut v[..3] {
            *x *= 1000.0;
        }
    }
    let r = check_pose_session(&s);
    let f = only(&r, "pose_units");
    assert_eq!(f.severity, Severity::Fatal);
    assert!((f.value - 600.0).abs() < 1.0, "{}", f.value);
    assert!(f.message.contains("poses in mm?"), "{}", f.message);
    assert!(f.action.contains("--units mm"), "{}", f.action);
    // each rule alone: a range over 10 m; a distance over 100 m; a speed
    // over 10 m/s
    let scaled = |f: &dyn Fn(usize, &mut [f64])| {
        let mut s = clean(60);
        for (i, v) in s.poses.values.chunks_exact_mut(7).enumerate() {
            f(i, &mut v[..3]);
        }
        check_pose_session(&s)
    };
    let range = scaled(&|_, p| p.iter_mut().for_each(|x| *x *= 20.0));
    assert!((only(&range, "pose_units").value - 12.0).abs() < 0.1);
    let far = scaled(&|_, p| p[2] += 500.0);
    assert_eq!(only(&far, "pose_units").severity, Severity::Fatal);
    let fast = scaled(&|i, p| p[0] = if i % 2 == 0 { 0.0 } else { 0.15 });
    assert!(only(&fast, "pose_units").message.contains("exceed 15.0"));
    assert!(!kinds(&scaled(&|_, p| p[2] += 5.0)).contains(&"pose_units"));
}

#[test]
fn a_two_second_gap_in_the_poses_is_named_with_its_time_and_length() {
    let mut s = clean(60);
    for t in s.poses.t.iter_mut().filter(|t| **t > 20.004) {
        *t += 2.0;
    }
    let r = check_pose_session(&s);
    let f = r
        .findings
        .iter()
        .find(|f| f.kind == "gap" && f.subject == "poses.csv")
        .expect("gap");
    assert!((f.value - 2.01).abs() < 1e-9, "{}", f.value);
    assert_eq!(f.severity, Severity::Warning);
    assert!(f.message.contains("at t = 20.000 s"), "{}", f.message);
    // the gap is not jitter
    assert!(!kinds(&r).contains(&"jitter"), "{:#?}", r.findings);
}

#[test]
fn pose_jitter_is_named() {
    let mut s = clean(60);
    for (i, t) in s.poses.t.iter_mut().enumerate() {
        *t += 0.002 * ((i * 7919 % 101) as f64 / 50.0 - 1.0);
    }
    let r = check_pose_session(&s);
    let f = only(&r, "jitter");
    assert_eq!(
        (f.subject.as_str(), f.severity),
        ("poses.csv", Severity::Warning)
    );
    assert!(f.value > 1e-3 && f.value < 4e-3, "{}", f.value);
}

#[test]
fn a_startup_burst_of_late_imu_stamps_is_counted() {
    let mut s = clean(60);
    // the first 30 IMU samples stamped 0.2 ms apart
    let t = &mut s.imus[0].samples.t;
    for (i, v) in t.iter_mut().take(30).enumerate() {
        *v = 0.145 - (29 - i) as f64 * 0.0002;
    }
    let r = check_pose_session(&s);
    let f = only(&r, "startup_burst");
    assert_eq!((f.value, f.subject.as_str()), (30.0, "imu.csv"));
    assert!(f.message.contains("within 5.8 ms"), "{}", f.message);
}

#[test]
fn a_saturated_gyro_channel_is_counted() {
    let mut s = clean(60);
    let fs = 125f64.to_radians();
    let imu = &mut s.imus[0].samples;
    for i in 400..460 {
        imu.values[6 * i + 3] = fs;
    }
    let r = check_pose_session(&s);
    let f = only(&r, "saturation");
    assert_eq!((f.subject.as_str(), f.value), ("gx", 60.0));
    assert!(f.message.contains("±125 °/s"), "{}", f.message);
    // with the range recorded, it is counted against it, per sensor
    let mut range = toml::Table::new();
    range.insert("gyro_range".into(), "Dps125".into());
    s.meta.imu = Some(range);
    let f = only(&check_pose_session(&s), "saturation").clone();
    assert_eq!((f.subject.as_str(), f.value), ("gyroscope", 60.0));
}

#[test]
fn streams_that_do_not_overlap_are_fatal() {
    let mut s = clean(30);
    for t in &mut s.imus[0].samples.t {
        *t += 1000.0;
    }
    let r = check_pose_session(&s);
    let f = only(&r, "overlap");
    assert_eq!(f.severity, Severity::Fatal);
    assert!(
        f.message.contains("poses.csv 0.000..29.990 s"),
        "{}",
        f.message
    );
}

/// Sessions of one row, or of rows at one instant, are checked without a
/// panic: the streams have no rate (fatal), nothing else is computed from
/// intervals it does not have.
#[test]
fn degenerate_sessions_do_not_panic() {
    let mut s = clean(1);
    s.poses.t.truncate(1);
    s.poses.values.truncate(7);
    s.imus[0].samples.t = vec![0.0, 0.0];
    s.imus[0].samples.values.truncate(12);
    let r = check_pose_session(&s);
    let rates: Vec<_> = r.findings.iter().filter(|f| f.kind == "rate").collect();
    assert_eq!(rates.len(), 2, "{:#?}", r.findings);
    assert!(rates.iter().all(|f| f.severity == Severity::Fatal));
    assert!(!kinds(&r).contains(&"jitter") && !kinds(&r).contains(&"startup_burst"));
}

/// A session of the pose simulator (consistent poses and IMU samples:
/// a hand-held-like motion about varying axes), 20 s, 15 Hz poses.
fn simulated(seed: u64) -> PoseSession {
    use crate::pose_calibrate::draw_pose_truth;
    use crate::pose_calibrate::simulate::test_support as sim;
    let m = sim::simulated(
        &draw_pose_truth(seed),
        20.0,
        seed,
        seed,
        &Default::default(),
    )
    .data;
    let pv = (0..m.pose_t.len())
        .flat_map(|k| m.pose_p[k].into_iter().chain(m.pose_q[k]))
        .collect();
    let iv = m.imu_z.iter().flatten().copied().collect();
    PoseSession {
        dir: "mem".into(),
        meta: PoseSessionMeta::default(),
        poses: table(&POSE_COLUMNS, m.pose_t, pv),
        imus: vec![ImuTable {
            samples: table(&IMU_COLUMNS, m.imu_t, iv),
            temp: None,
        }],
        truth: None,
    }
}

/// Quaternions of the inverse rotation (conjugated: the same numbers in
/// JPL's convention) are fatal and named with the alignments' RMS ratio;
/// the same session as simulated (R_WB) has no such finding.
#[test]
fn the_inverse_rotation_convention_is_named() {
    for seed in [1, 2] {
        let good = simulated(seed);
        let r = check_pose_session(&good);
        assert!(
            !kinds(&r).contains(&"rotation_convention"),
            "{:#?}",
            r.findings
        );
        let mut inverse = good;
        for row in inverse.poses.values.chunks_mut(7) {
            for v in &mut row[4..7] {
                *v = -*v;
            }
        }
        let r = check_pose_session(&inverse);
        let f = only(&r, "rotation_convention");
        assert_eq!(f.severity, Severity::Fatal);
        eprintln!("seed {seed}: {}", f.message);
        assert!(f.value < convention::INVERSE_RATIO, "{}", f.value);
        assert!(f.message.contains("inverse rotation"), "{}", f.message);
        assert!(
            f.action.contains("--conjugate") && f.action.contains("−qx, −qy, −qz"),
            "{}",
            f.action
        );
    }
}
