//! Running the `robimu` program from the integration tests: one way for
//! every test file (`mod common;`).
//!
//! * [`robimu`] runs it with arguments and returns its [`Run`] (exit status,
//!   stdout, stderr as text);
//! * [`robimu_ok`] also asserts that it succeeded, printing both streams
//!   when not;
//! * [`Run::assert_fails`] asserts a clean failure (non-zero exit, an
//!   `error: ` line naming the causes, no panic);
//! * [`command`] is the bare [`Command`] for the tests that set the
//!   environment or standard streams themselves or [`Command::spawn`] the
//!   program; [`Run::from`] turns its [`Output`] into a [`Run`].

// Each test binary uses its own part of this module.
#![allow(dead_code)]

use std::ffi::OsStr;
use std::fmt::Debug;
use std::path::Path;
use std::process::{Command, ExitStatus, Output};

/// The `robimu` program (built by cargo for the integration tests), not
/// yet started.
pub fn command() -> Command {
    Command::new(env!("CARGO_BIN_EXE_robimu"))
}

/// Outcome of one run of the program.
#[derive(Debug, Clone)]
pub struct Run {
    /// How it ended.
    pub status: ExitStatus,
    /// Standard output (lossy UTF-8).
    pub stdout: String,
    /// Standard error (lossy UTF-8).
    pub stderr: String,
}

impl From<Output> for Run {
    fn from(out: Output) -> Self {
        Self {
            status: out.status,
            stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
            stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
        }
    }
}

impl Run {
    /// Exit code (`None` when killed by a signal).
    pub fn code(&self) -> Option<i32> {
        self.status.code()
    }

    /// Exit code 0.
    pub fn success(&self) -> bool {
        self.status.success()
    }

    /// Standard output followed by standard error.
    pub fn text(&self) -> String {
        format!("{}{}", self.stdout, self.stderr)
    }

    /// Asserts a non-zero exit, no panic, an `error: ` line and every `wants`
    /// in stderr.
    #[track_caller]
    pub fn assert_fails(&self, wants: &[&str]) {
        assert!(
            self.code().is_some_and(|c| c != 0),
            "expected failure, got {:?}\nstdout:\n{}",
            self.code(),
            self.stdout
        );
        assert!(!self.stderr.contains("panicked"), "panic:\n{}", self.stderr);
        assert!(
            self.stderr.lines().any(|l| l.starts_with("error: ")),
            "{}",
            self.stderr
        );
        for want in wants {
            assert!(
                self.stderr.contains(want),
                "stderr lacks `{want}`:\n{}",
                self.stderr
            );
        }
    }
}

/// Runs `robimu ARGS…` to its end.
#[track_caller]
pub fn robimu<I>(args: I) -> Run
where
    I: IntoIterator,
    I::Item: AsRef<OsStr>,
{
    command()
        .args(args)
        .output()
        .expect("the robimu binary runs")
        .into()
}

/// Runs `robimu ARGS…` and asserts that it succeeded (exit code 0; both
/// streams and the arguments are printed when not).
#[track_caller]
pub fn robimu_ok<I>(args: I) -> Run
where
    I: IntoIterator,
    I::Item: AsRef<OsStr> + Debug,
{
    let args: Vec<I::Item> = args.into_iter().collect();
    let run = robimu(&args);
    assert!(
        run.success(),
        "robimu {args:?} failed ({}):\nstdout:\n{}\nstderr:\n{}",
        run.status,
        run.stdout,
        run.stderr
    );
    run
}

/// One real-time test at a time in a test binary: hold the guard for the
/// whole test. The simulated board and controller of a recording are
/// threads on the host's cores, and miss their sample deadlines (counted as
/// the board's own drops, a lower joint rate) when the binary's other tests
/// calibrate on both cores meanwhile. A failed test's poisoned lock is taken
/// over.
pub fn real_time_slot() -> std::sync::MutexGuard<'static, ()> {
    static SLOT: std::sync::Mutex<()> = std::sync::Mutex::new(());
    SLOT.lock().unwrap_or_else(|e| e.into_inner())
}

/// One IMU stream of a real-time recording lost nothing unseen: every
/// sequence gap is a slot the board itself missed and counted (a host that
/// stalls the simulated board's thread past a sample deadline makes it drop
/// and count the sample, as the real board does on an overrun: how many
/// depends on the machine's load, not on robimu; the count is the board's
/// report after Stop, which may also hold drops after the last sample the
/// host read, so it may exceed the gaps), and the delivered and the missed
/// slots together fill the configured rate over the recording, to 1 %.
#[track_caller]
pub fn assert_every_slot_accounted(
    samples: u64,
    seq_gaps: u64,
    dropped: u32,
    rate_hz: f64,
    duration: f64,
) {
    assert!(
        seq_gaps <= u64::from(dropped),
        "{seq_gaps} sequence gaps, of which the board counted only {dropped} as its own drops"
    );
    let slots = (samples + seq_gaps) as f64;
    let want = rate_hz * duration;
    assert!(
        (slots - want).abs() <= 0.01 * want,
        "{samples} samples + {seq_gaps} missed slots over {duration} s at {rate_hz} Hz (want {want:.0})"
    );
    eprintln!("slots: {samples} samples + {seq_gaps} missed = {slots} (rate x duration {want:.1})");
}

/// A JSON array of arrays of numbers (a result file's covariance `matrix`).
pub fn json_matrix(v: &serde_json::Value) -> Vec<Vec<f64>> {
    v.as_array()
        .expect("an array of rows")
        .iter()
        .map(|row| {
            row.as_array()
                .expect("a row")
                .iter()
                .map(|x| x.as_f64().expect("a number"))
                .collect()
        })
        .collect()
}

/// `p` as a command-line argument (temporary paths are UTF-8).
pub fn s(p: &Path) -> &str {
    p.to_str().expect("temporary paths are UTF-8")
}

/// Checks every string the figures (`*.svg`) in `dir` draw against the
/// embedded font's cmap (host/report/assets, ab_glyph: no character maps to
/// glyph 0, which renders as a blank in the PNGs); returns how many strings
/// were checked. plotters writes each string drawn as one `<text>` element.
pub fn assert_figure_glyphs(dir: &Path) -> usize {
    use ab_glyph::{Font, FontRef, GlyphId};
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../report/assets/DejaVuSans-subset.ttf");
    let bytes = std::fs::read(&path).unwrap();
    let font = FontRef::try_from_slice(&bytes).unwrap();
    let mut checked = 0;
    let mut bad = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let file = entry.unwrap().path();
        if file.extension().is_none_or(|e| e != "svg") {
            continue;
        }
        let svg = std::fs::read_to_string(&file).unwrap();
        for piece in svg.split("<text").skip(1) {
            let body = &piece[piece.find('>').unwrap() + 1..piece.find("</text>").unwrap()];
            let text = body
                .trim_matches('\n')
                .replace("&lt;", "<")
                .replace("&gt;", ">")
                .replace("&quot;", "\"")
                .replace("&apos;", "'")
                .replace("&amp;", "&");
            let missing: String = text
                .chars()
                .filter(|&c| font.glyph_id(c) == GlyphId(0))
                .collect();
            if !missing.is_empty() {
                bad.push(format!("{}: `{text}` lacks {missing:?}", file.display()));
            }
            checked += 1;
        }
    }
    assert!(
        bad.is_empty(),
        "characters the embedded font lacks: {bad:#?}"
    );
    assert!(checked > 0, "no figure text in {}", dir.display());
    checked
}

/// The whole diagnosis of `data` with the default catalogue set-up and
/// calibration options, and `dopts` (docs/model.md §4.5).
pub fn diagnose_with(
    robot: &robimu_model::Robot,
    data: &robimu_model::observations::Measurements,
    dopts: &robimu_workflows::diagnose::DiagnoseOptions,
) -> (
    robimu_model::effects::CatalogueSetup,
    robimu_workflows::diagnose::Diagnosis,
) {
    let setup = robimu_workflows::diagnose::setup_for(robot, data, None);
    let opts = robimu_workflows::calibrate::CalibrateOptions::new(robot);
    let d =
        robimu_workflows::diagnose::diagnose(robot, data, &opts, &setup, dopts, |_| {}).unwrap();
    (setup, d)
}

/// [`diagnose_with`] the default options.
pub fn diagnose_all(
    robot: &robimu_model::Robot,
    data: &robimu_model::observations::Measurements,
) -> (
    robimu_model::effects::CatalogueSetup,
    robimu_workflows::diagnose::Diagnosis,
) {
    diagnose_with(robot, data, &Default::default())
}

/// One row of a poses CSV as `tests/ur_kinematics_fk.py fk` and
/// `tests/makers_fk.py --poses` read it: the joint angles `q`, then the
/// position of `t` and its rotation matrix row by row, each to the bit.
pub fn pose_row(q: &[f64], t: &robimu_model::geom::Iso) -> String {
    let mut row: Vec<String> = q.iter().map(|v| format!("{v:?}")).collect();
    row.extend(t.p.iter().map(|v| format!("{v:?}")));
    row.extend(t.r.iter().flatten().map(|v| format!("{v:?}")));
    row.join(",") + "\n"
}

/// A result.json (docs/model.md §8 shape, `robot` its robot spec) holding
/// the value `value(spec)` for every parameter of `layout`, each frozen
/// with σ 0 and no covariance: a calibration to export.
pub fn write_result_json(
    path: &Path,
    robot: &str,
    layout: &robimu_model::ParamLayout,
    mut value: impl FnMut(&robimu_model::ParamSpec) -> f64,
) {
    let params: Vec<_> = layout
        .specs()
        .iter()
        .map(|p| {
            serde_json::json!({"name": p.name, "unit": p.unit, "value": value(p), "prior": p.nominal,
                "prior_sigma": p.sigma, "sigma": 0.0, "frozen": true})
        })
        .collect();
    let json = serde_json::json!({"format": "robimu-result/1", "parameters": params,
        "covariance": {"names": [], "matrix": []}, "robot": robot});
    std::fs::write(path, json.to_string()).unwrap();
}

/// IMU samples as EuRoC's `imu0/data.csv`: ns stamps, the gyroscope's
/// columns first (rad/s), then the accelerometer's (m/s²); `z` in robimu's
/// order [ax, ay, az, gx, gy, gz], written to round-trip exactly.
pub fn euroc_imu_csv(samples: impl IntoIterator<Item = (i64, [f64; 6])>) -> String {
    let mut text = String::from(
        "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],\
         a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n",
    );
    for (ns, z) in samples {
        text.push_str(&format!(
            "{ns},{:?},{:?},{:?},{:?},{:?},{:?}\n",
            z[3], z[4], z[5], z[0], z[1], z[2]
        ));
    }
    text
}
