//! The built-in robots against their makers' descriptions, checked by an
//! independent implementation: `tests/makers_fk.py` (numpy forward
//! kinematics of the maker's URDF XML in tests/fixtures/makers/, whose header
//! names the maker's repository, file and commit, against its own reading of
//! host/model/robots/*.toml) at 200 random configurations, to 1e-6 m and
//! 1e-6 rad. Skipped, with a message, when python3 or numpy is missing
//! (`.ci/run` installs numpy).

use std::path::Path;
use std::process::Command;

#[test]
fn builtins_equal_their_makers_urdf_by_an_independent_reader() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let probe = Command::new("python3")
        .args(["-c", "import numpy, tomllib"])
        .output();
    match probe {
        Ok(o) if o.status.success() => {}
        _ => {
            eprintln!("SKIPPED: python3 >= 3.11 with numpy is needed (pip install numpy)");
            return;
        }
    }
    let out = Command::new("python3")
        .arg(root.join("tests/makers_fk.py"))
        .arg(&root)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    println!("{text}{}", String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "tests/makers_fk.py failed:\n{text}");
    for name in ["ur5e", "ur10e", "fr3", "panda", "iiwa14", "gen3"] {
        assert!(
            text.lines()
                .any(|l| l.starts_with(&format!("{name} ")) && l.ends_with(" ok")),
            "{name} not checked:\n{text}"
        );
    }
    let checked = text.lines().filter(|l| l.ends_with(" ok")).count();
    assert_eq!(
        checked,
        robimu_model::BUILTIN_ROBOTS.len() - 1,
        "every built-in but aubo_i5"
    );
}
