//! `robimu check` and the verdict (issue 17): sessions from `simulate`
//! altered in one way each — gyroscope in deg/s, accelerometer in g,
//! swapped accelerometer/gyroscope columns, timestamps in ms, a 3 s gap, a
//! stuck channel, a motionless recording, a NaN, saturation — are each named
//! with their number and exit non-zero where fatal; good simulated sessions
//! (20 seeds, in-process) have no fatal finding; `calibrate` stops on a
//! fatal finding; its verdict is "trust: good" on a good session and not
//! good, with the reason, on one with an unmodelled sensor delay.

mod common;

use std::path::Path;

use common::{robimu, robimu_ok, s};
use robimu_model::Robot;
use robimu_session::{SessionMeta, Table, IMU_COLUMNS};
use robimu_workflows::check::{check_session, CheckOptions, CheckReport, Severity};
use robimu_workflows::simulate::{random_session, SimulateOptions};

/// Copies the session `src` to `dst`, rewriting `file`'s data rows with
/// `f` (a row `None` is dropped).
fn altered(src: &Path, dst: &Path, file: &str, f: impl Fn(Vec<f64>) -> Option<Vec<f64>>) {
    std::fs::create_dir_all(dst).unwrap();
    for name in ["session.toml", "joints.csv", "imu.csv"] {
        std::fs::copy(src.join(name), dst.join(name)).unwrap();
    }
    let text = std::fs::read_to_string(src.join(file)).unwrap();
    let mut lines = text.lines();
    let mut out = format!("{}\n", lines.next().unwrap());
    for line in lines {
        let row: Vec<f64> = line.split(',').map(|v| v.parse().unwrap()).collect();
        if let Some(r) = f(row) {
            let cells: Vec<String> = r.iter().map(|v| format!("{v:e}")).collect();
            out.push_str(&cells.join(","));
            out.push('\n');
        }
    }
    std::fs::write(dst.join(file), out).unwrap();
}

/// `robimu check DIR --json`: the run and its findings (kind, severity, value, message).
fn check(dir: &Path) -> (common::Run, Vec<serde_json::Value>) {
    let json = dir.join("check.json");
    let run = robimu(["check", s(dir), "--json", s(&json)]);
    assert!(!run.stderr.contains("panicked"), "{}", run.stderr);
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    (run, v["findings"].as_array().unwrap().clone())
}

fn finding<'a>(findings: &'a [serde_json::Value], kind: &str) -> &'a serde_json::Value {
    findings
        .iter()
        .find(|f| f["kind"] == kind)
        .unwrap_or_else(|| panic!("no `{kind}` finding in {findings:#?}"))
}

fn value(f: &serde_json::Value) -> f64 {
    f["value"].as_f64().unwrap()
}

fn fatal(findings: &[serde_json::Value]) -> Vec<&serde_json::Value> {
    findings
        .iter()
        .filter(|f| f["severity"] == "fatal")
        .collect()
}

/// A fatal `kind`, the only fatal finding, the run failing with its message.
#[track_caller]
fn only_fatal<'a>(
    run: &common::Run,
    findings: &'a [serde_json::Value],
    kind: &str,
    text: &str,
) -> &'a serde_json::Value {
    let f = finding(findings, kind);
    assert_eq!(f["severity"], "fatal", "{f:#}");
    let all = fatal(findings);
    assert!(all.iter().all(|x| x["kind"] == kind), "{all:#?}");
    let msg = f["message"].as_str().unwrap();
    assert!(msg.contains(text), "{msg}");
    run.assert_fails(&[text]);
    assert!(run.stdout.contains(text), "{}", run.stdout);
    f
}

/// The root-mean-square of column `c` of imu.csv over its rows.
fn imu_rows(dir: &Path) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(dir.join("imu.csv")).unwrap();
    text.lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect()
}

#[test]
fn each_alteration_is_named_with_its_number() {
    let tmp = tempfile::tempdir().unwrap();
    let good = tmp.path().join("good");
    robimu_ok([
        "simulate",
        "--duration",
        "40",
        "--seed",
        "3",
        "--out",
        s(&good),
    ]);
    let (run, base) = check(&good);
    assert!(run.success(), "{}{}", run.stdout, run.stderr);
    assert!(fatal(&base).is_empty(), "{base:#?}");
    let ratio = value(finding(&base, "gyro_units"));
    let radius = value(finding(&base, "accel_units"));
    assert!(
        (0.6..1.6).contains(&ratio) && (6.8..12.8).contains(&radius),
        "{ratio} {radius}"
    );

    // gyroscope in deg/s: the ratio scales by exactly 180/π
    let dir = tmp.path().join("deg");
    altered(&good, &dir, "imu.csv", |mut r| {
        r[4..7].iter_mut().for_each(|v| *v = v.to_degrees());
        Some(r)
    });
    let (run, f) = check(&dir);
    let g = only_fatal(&run, &f, "gyro_units", "gyroscope in deg/s?");
    let want = ratio * 180.0 / std::f64::consts::PI;
    assert!(
        (value(g) / want - 1.0).abs() < 1e-6,
        "{} against {want}",
        value(g)
    );
    assert!(g["message"]
        .as_str()
        .unwrap()
        .contains(&format!("ratio {want:.2}")));

    // joints in degrees: named as such (not blamed on the gyroscope), the
    // value the first sample beyond the robot's limits
    let dir = tmp.path().join("joints_deg");
    altered(&good, &dir, "joints.csv", |mut r| {
        r[1..].iter_mut().for_each(|v| *v = v.to_degrees());
        Some(r)
    });
    let (run, f) = check(&dir);
    let j = only_fatal(&run, &f, "joint_units", "are the joints in radians?");
    let robot = Robot::aubo_i5();
    let lim = robot.limits();
    let v = value(j);
    assert!(
        lim.iter().any(|l| v < l.q_min - 0.2 || v > l.q_max + 0.2),
        "{v} is within every joint's limits"
    );

    // accelerometer in g: the sphere's radius scales by 1/g
    let dir = tmp.path().join("g");
    altered(&good, &dir, "imu.csv", |mut r| {
        r[1..4].iter_mut().for_each(|v| *v /= 9.80665);
        Some(r)
    });
    let (run, f) = check(&dir);
    let a = only_fatal(&run, &f, "accel_units", "accelerometer not in m/s²?");
    assert!(
        (value(a) / (radius / 9.80665) - 1.0).abs() < 1e-6,
        "{}",
        value(a)
    );
    assert!(a["message"]
        .as_str()
        .unwrap()
        .contains(&format!("= {:.2}", radius / 9.80665)));
    assert!(a["message"].as_str().unwrap().contains("in g"));

    // swapped columns: the gyroscope columns carry the accelerometer's median |a|
    let dir = tmp.path().join("swap");
    altered(&good, &dir, "imu.csv", |r| {
        Some([&r[..1], &r[4..7], &r[1..4]].concat())
    });
    let (run, f) = check(&dir);
    let w = only_fatal(&run, &f, "swapped_columns", "columns swapped?");
    let mut norms: Vec<f64> = imu_rows(&good)
        .iter()
        .map(|r| (r[1] * r[1] + r[2] * r[2] + r[3] * r[3]).sqrt())
        .collect();
    norms.sort_by(f64::total_cmp);
    let median = norms[norms.len() / 2];
    assert!(
        (value(w) - median).abs() < 1e-9,
        "{} against {median}",
        value(w)
    );

    // timestamps in ms, in both files: the rate 1000× too low
    let dir = tmp.path().join("ms");
    altered(&good, &dir, "imu.csv", |mut r| {
        r[0] *= 1e3;
        Some(r)
    });
    let ms = tmp.path().join("ms2");
    altered(&dir, &ms, "joints.csv", |mut r| {
        r[0] *= 1e3;
        Some(r)
    });
    let (run, f) = check(&ms);
    let t = only_fatal(&run, &f, "time_unit", "timestamps in ms?");
    assert!((value(t) - 0.12).abs() < 1e-9, "{}", value(t));
    assert_eq!(f.iter().filter(|x| x["kind"] == "time_unit").count(), 2);

    // a 3 s gap in imu.csv: a warning naming it, no fatal
    let dir = tmp.path().join("gap");
    altered(&good, &dir, "imu.csv", |r| {
        (!(r[0] > 20.0 && r[0] < 23.0)).then_some(r)
    });
    let (run, f) = check(&dir);
    assert!(run.success(), "{}", run.stderr);
    let gap = finding(&f, "gap");
    assert_eq!(gap["severity"], "warning");
    assert!((value(gap) - 3.0).abs() < 1e-6, "{}", value(gap));
    let msg = gap["message"].as_str().unwrap();
    assert!(
        msg.contains("largest gap 3.000 s at t = 20.000 s") && msg.contains("1 gap(s)"),
        "{msg}"
    );

    // a stuck channel: gx constant
    let dir = tmp.path().join("stuck");
    let first = imu_rows(&good)[0][4];
    altered(&good, &dir, "imu.csv", |mut r| {
        r[4] = first;
        Some(r)
    });
    let (run, f) = check(&dir);
    let st = only_fatal(&run, &f, "stuck", "gx is constant");
    assert_eq!(st["subject"], "gx");
    assert_eq!(value(st), first);

    // a NaN: the reader's file and line
    let dir = tmp.path().join("nan");
    altered(&good, &dir, "imu.csv", |mut r| {
        if (r[0] - 1.0).abs() < 1e-9 {
            r[5] = f64::NAN;
        }
        Some(r)
    });
    let (run, f) = check(&dir);
    only_fatal(
        &run,
        &f,
        "unreadable",
        "imu.csv:122: column `gy`: NaN is not a finite number",
    );

    // saturation: a ±2 g accelerometer clipping
    let dir = tmp.path().join("sat");
    let range = 2.0 * 9.80665;
    altered(&good, &dir, "imu.csv", |mut r| {
        r[1] = (3.0 * r[1]).clamp(-range, range);
        Some(r)
    });
    let toml = std::fs::read_to_string(good.join("session.toml")).unwrap();
    std::fs::write(
        dir.join("session.toml"),
        format!("{toml}\n[imu]\naccel_range = \"G2\"\n"),
    )
    .unwrap();
    let clipped = imu_rows(&dir)
        .iter()
        .filter(|r| r[1..4].iter().any(|v| v.abs() >= 0.98 * range))
        .count();
    assert!(clipped > 0);
    let (_, f) = check(&dir);
    let sat = finding(&f, "saturation");
    assert_eq!(value(sat), clipped as f64);
}

#[test]
fn a_motionless_recording_is_fatal() {
    let tmp = tempfile::tempdir().unwrap();
    let plan = tmp.path().join("plan");
    std::fs::create_dir_all(&plan).unwrap();
    let mut text = String::from("t,q1,q2,q3,q4,q5,q6\n");
    for i in 0..=30 {
        text.push_str(&format!("{i},0.1,0.2,1.0,0.4,0.5,0.6\n"));
    }
    std::fs::write(plan.join("plan.csv"), text).unwrap();
    let dir = tmp.path().join("still");
    robimu_ok([
        "simulate",
        "--trajectory",
        s(&plan),
        "--seed",
        "2",
        "--out",
        s(&dir),
    ]);
    let (run, f) = check(&dir);
    let m = only_fatal(&run, &f, "motionless", "the robot does not move");
    // the joints' noise alone: far below the threshold, above 0
    assert!(value(m) > 0.0 && value(m) < 0.01, "{}", value(m));
    assert!(f.iter().all(|x| x["kind"] != "gyro_units"), "{f:#?}");
}

/// A session in memory from the simulator's samples.
fn session_of(robot: &Robot, seed: u64, duration: f64) -> robimu_session::Session {
    let opts = SimulateOptions::paper(robot);
    let sim = random_session(robot, duration, 1.0, &opts, seed).unwrap();
    let d = sim.data;
    robimu_session::Session {
        dir: format!("seed{seed}").into(),
        meta: SessionMeta::new("aubo_i5"),
        joints: Table {
            columns: (1..=robot.dof()).map(|i| format!("q{i}")).collect(),
            t: d.joint_t,
            values: d.joint_q,
        },
        imu: Table {
            columns: IMU_COLUMNS.iter().map(|c| c.to_string()).collect(),
            t: d.imu_t,
            values: d.imu_z.iter().flatten().copied().collect(),
        },
        imu_temp: None,
        extra_imus: Vec::new(),
        tracker: None,
        truth: None,
    }
}

#[test]
fn good_sessions_have_no_fatal_finding() {
    let robot = Robot::aubo_i5();
    for seed in 1..=20 {
        let session = session_of(&robot, seed, 40.0);
        let report: CheckReport = check_session(&session, &robot, &CheckOptions::default());
        assert!(report.fatal().is_none(), "seed {seed}: {report:#?}");
        // a warning only for what this motion leaves undetermined
        let warnings: Vec<_> = report.of(Severity::Warning).collect();
        assert!(
            warnings.iter().all(|f| f.kind == "excitation"),
            "seed {seed}: {warnings:#?}"
        );
        // the checks ran: the unit checks and the excitation measure
        for kind in ["accel_units", "gyro_units", "excitation", "overlap"] {
            assert!(report.find(kind).is_some(), "seed {seed}: no {kind}");
        }
    }
}

#[test]
fn calibrate_stops_on_a_fatal_finding_and_gives_a_verdict() {
    let tmp = tempfile::tempdir().unwrap();
    let good = tmp.path().join("good");
    robimu_ok([
        "simulate",
        "--duration",
        "40",
        "--seed",
        "5",
        "--out",
        s(&good),
    ]);
    let rep = tmp.path().join("report");
    let run = robimu_ok(["calibrate", s(&good), "--report", s(&rep)]);
    let verdict = run.stdout.find("verdict:").expect("a verdict");
    let table = run.stdout.find("parameter   unit").expect("the table");
    assert!(verdict < table, "the verdict comes first:\n{}", run.stdout);
    assert!(run.stdout.contains("\ntrust: good\n"), "{}", run.stdout);
    assert!(
        run.stdout.contains("residuals     white (Ljung-Box"),
        "{}",
        run.stdout
    );
    let result: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(good.join("result.json")).unwrap()).unwrap();
    assert_eq!(result["verdict"]["trust"], "good");
    let html = std::fs::read_to_string(rep.join("report.html")).unwrap();
    let (v, p) = (
        html.find("<h2>Verdict</h2>").unwrap(),
        html.find("<h2>Parameters</h2>").unwrap(),
    );
    assert!(v < p && html.contains("<b>trust: good</b>"));

    // unmodelled: a 100 ms accelerometer delay, a bias random walk 60× the
    // paper's; the residuals' correlation is beyond the AR noise model
    for (name, effect) in [
        ("delay", ["--effect", "sensor_delay=100"]),
        ("walk", ["--bias-walk", "60"]),
    ] {
        let dir = tmp.path().join(name);
        robimu_ok([
            "simulate",
            "--duration",
            "40",
            "--seed",
            "5",
            effect[0],
            effect[1],
            "--out",
            s(&dir),
        ]);
        // the paper's model alone: its residuals and its tests reject it
        let run = robimu_ok(["calibrate", s(&dir), "--model", "paper"]);
        let line = run
            .stdout
            .lines()
            .find(|l| l.starts_with("trust: "))
            .expect("a trust line");
        assert!(
            line.starts_with(
                "trust: doubtful — residuals: correlated beyond what the AR noise model captures ("
            ),
            "{name}: {line}"
        );
        assert!(line.contains("robimu diagnose"), "{line}");
        assert!(line.contains("model: the data reject the model"), "{line}");
        assert!(
            run.stdout.contains(&format!(
                "next: let the calibration add the effects the data show: robimu calibrate {}",
                s(&dir)
            )),
            "{}",
            run.stdout
        );
        let result: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("result.json")).unwrap())
                .unwrap();
        assert_eq!(result["verdict"]["trust"], "doubtful");
        assert!(
            result.get("effects").is_none(),
            "--model paper has no effects list"
        );
        // by default the calibration adds what the tests find: the delay
        if name == "delay" {
            let run = robimu_ok(["calibrate", s(&dir)]);
            let result: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(dir.join("result.json")).unwrap())
                    .unwrap();
            let effects: Vec<&str> = result["effects"]
                .as_array()
                .unwrap()
                .iter()
                .map(|e| e["name"].as_str().unwrap())
                .collect();
            assert_eq!(effects, ["sensor_delay"], "{}", run.stdout);
            let delay = &result["effects"][0]["parameters"][0];
            let (v, sd) = (
                delay["value"].as_f64().unwrap(),
                delay["sigma"].as_f64().unwrap(),
            );
            assert!((v - 0.1).abs() < 4.0 * sd, "delay {v} ± {sd}");
            assert!(
                result["effects"][0]["evidence"]["p_value"]
                    .as_f64()
                    .unwrap()
                    < 1e-6
            );
            assert_eq!(result["verdict"]["trust"], "good", "{}", run.stdout);
        }
    }
    // correlated sensor noise (AR(1), recorded in session.toml) is modelled: good
    let ar = tmp.path().join("ar");
    robimu_ok([
        "simulate",
        "--duration",
        "40",
        "--seed",
        "5",
        "--noise-model",
        "ar1:accel=20,gyro=10",
        "--out",
        s(&ar),
    ]);
    let run = robimu_ok(["calibrate", s(&ar)]);
    assert!(run.stdout.contains("\ntrust: good\n"), "{}", run.stdout);
    assert!(run.stdout.contains("correlated ("), "{}", run.stdout);

    // gyroscope in deg/s: calibrate stops before the fit with the finding
    let deg = tmp.path().join("deg");
    altered(&good, &deg, "imu.csv", |mut r| {
        r[4..7].iter_mut().for_each(|v| *v = v.to_degrees());
        Some(r)
    });
    let run = robimu(["calibrate", s(&deg)]);
    run.assert_fails(&["gyroscope in deg/s?", "robimu check"]);
    assert!(!run.stdout.contains("iter"), "no fit:\n{}", run.stdout);
    assert!(!deg.join("result.json").exists());
}
