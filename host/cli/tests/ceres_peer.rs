//! robimu against an independent implementation of its problem: the Ceres
//! 2.1 program of `peers/ceres` (its own kinematics by the recursion of
//! paper eq. (4), autodiff, Ceres's Levenberg–Marquardt and its own
//! covariance), which shares no code with robimu. On a simulated session
//! (files on disk, the interchange format of docs/model.md §7–8) both must
//! find the same minimum of the same cost and the same marginal covariance.
//!
//! Needs a C++ compiler and Ceres (Debian: `apt-get install libceres-dev`),
//! hence ignored by default:
//! `cargo test -p robimu --test ceres_peer -- --ignored`.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

mod common;
use common::{json_matrix, robimu_ok, s};

/// Runs `cmd`, asserting success with `what` and its error output.
fn succeed(cmd: &mut Command, what: &str) -> Output {
    let out = cmd
        .output()
        .unwrap_or_else(|e| panic!("{what}: cannot start: {e}"));
    assert!(
        out.status.success(),
        "{what} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Builds the peer with `peers/ceres/build.sh`.
fn build_peer() -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let exe = Path::new(env!("CARGO_TARGET_TMPDIR")).join("robimu_ceres");
    succeed(
        Command::new("sh")
            .arg(root.join("peers/ceres/build.sh"))
            .arg(&exe),
        "building the Ceres peer (Debian: apt-get install g++ libceres-dev)",
    );
    exe
}

fn read(path: &Path) -> Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn number(v: &Value, key: &str) -> f64 {
    v[key]
        .as_f64()
        .unwrap_or_else(|| panic!("no number {key} in a result"))
}

#[test]
#[ignore = "needs g++ and libceres-dev; run with --ignored"]
fn an_independent_ceres_implementation_finds_the_same_estimate_and_covariance() {
    let peer = build_peer();
    let work = tempfile::tempdir().unwrap();
    let session = work.path().join("session");
    // the two streams on grids of their own (docs/model.md §4.2)
    robimu_ok([
        "simulate",
        "--duration",
        "120",
        "--seed",
        "3",
        "--rate",
        "100",
        "--joint-rate",
        "125",
        "--out",
        s(&session),
    ]);
    let ours_path = work.path().join("robimu.json");
    robimu_ok(["calibrate", s(&session), "--out", s(&ours_path)]);
    let ours = read(&ours_path);

    // The peer starts where robimu's τ search and knot choice ended (it has
    // neither) and runs Levenberg–Marquardt to its rounding level.
    let theirs_path = work.path().join("ceres.json");
    let out = succeed(
        Command::new(&peer)
            .arg(&session)
            .args(["--tau", &number(&ours, "tau_initial").to_string()])
            .args(["--knot-spacing", &number(&ours, "knot_spacing").to_string()])
            .args(["--function-tolerance", "1e-15", "--out"])
            .arg(&theirs_path),
        "the Ceres peer",
    );
    eprintln!("{}", String::from_utf8_lossy(&out.stderr));
    let theirs = read(&theirs_path);

    // Same samples, same cost at the minimum (J = ½‖r‖², whitened).
    assert_eq!(ours["imu_samples_used"], theirs["imu_samples_used"]);
    let (j_ours, j_theirs) = (number(&ours, "final_cost"), number(&theirs, "final_cost"));
    assert!(
        ((j_ours - j_theirs) / j_ours).abs() < 1e-10,
        "final cost: robimu {j_ours}, Ceres {j_theirs}"
    );

    // Same estimate (robimu stops within 1e-6 marginal σ of its minimum:
    // docs/model.md §4.4) and the same marginal σ.
    let ours_p = ours["parameters"].as_array().unwrap();
    let theirs_p = theirs["parameters"].as_array().unwrap();
    assert_eq!(ours_p.len(), theirs_p.len());
    let (mut dv, mut ds) = (0.0_f64, 0.0_f64);
    for (a, b) in ours_p.iter().zip(theirs_p) {
        assert_eq!(a["name"], b["name"], "parameter order (docs/model.md §5)");
        let sigma = number(a, "sigma");
        assert!(sigma > 0.0);
        dv = dv.max((number(a, "value") - number(b, "value")).abs() / sigma);
        ds = ds.max((sigma - number(b, "sigma")).abs() / sigma);
    }
    eprintln!("max |Δvalue|/σ = {dv:.2e}, max |Δσ|/σ = {ds:.2e}");
    assert!(dv < 1e-5, "estimates differ by {dv} σ");
    assert!(ds < 1e-5, "σ differ by {ds} relative");

    // The whole marginal covariance, entry by entry in units of σ_i σ_j.
    assert_eq!(ours["covariance"]["names"], theirs["covariance"]["names"]);
    let ca = json_matrix(&ours["covariance"]["matrix"]);
    let cb = json_matrix(&theirs["covariance"]["matrix"]);
    let mut dc = 0.0_f64;
    for i in 0..ca.len() {
        for j in 0..ca.len() {
            let scale = (ca[i][i] * ca[j][j]).sqrt();
            dc = dc.max((ca[i][j] - cb[i][j]).abs() / scale);
        }
    }
    eprintln!("max |ΔC_ij|/(σ_i σ_j) = {dc:.2e}");
    assert!(dc < 1e-5, "covariances differ by {dc} (correlation units)");
}
