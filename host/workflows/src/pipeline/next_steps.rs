//! What to do when a calibration's verdict is not good: one command a user
//! can paste per failed check (docs/model.md §8.2).

use robimu_session::result::{ModelTestsRecord, Trust, VerdictRecord};
use robimu_session::Session;

/// Commands for the failed checks of `v` on `session` (none when the trust
/// is good).
pub(super) fn next_steps(
    v: &VerdictRecord,
    session: &Session,
    tests: &ModelTestsRecord,
) -> Vec<String> {
    if v.trust == Trust::Good {
        return Vec::new();
    }
    let dir = session.dir.display().to_string();
    let robot = &session.meta.robot;
    let (t0, t1) = session.joints.span().unwrap_or_default();
    let longer = (2.0 * (t1 - t0)).max(300.0).round();
    let replan = format!(
        "record a longer, faster motion: robimu plan --robot {robot} --duration {longer} --out plan, then robimu record … --plan plan, then robimu calibrate on the new session"
    );
    let mut steps = Vec::new();
    let mut push = |s: String| {
        if !steps.contains(&s) {
            steps.push(s);
        }
    };
    for c in v.checks.iter().filter(|c| !c.ok) {
        match c.topic.as_str() {
            "converged" => {
                push(format!("find what keeps the fit from converging: robimu check {dir}"));
                push(replan.clone());
            }
            "residuals" | "structure" => {
                push(format!(
                    "see what the model lacks: robimu diagnose {dir} --out {dir}/diagnosis"
                ));
            }
            "model" => model_steps(tests, &dir, &mut push, &replan),
            "plausible" => push(format!(
                "check the IMU mount: the [imu.mount] table of {dir}/session.toml against the board's position and orientation on the flange (robimu check {dir})"
            )),
            "repeatability" => push(replan.clone()),
            _ => {}
        }
    }
    steps
}

/// The steps for effects the model lacks: the default calibration when the
/// paper's model was asked for, else fix the set or record a motion that
/// tells the effects apart.
fn model_steps(tests: &ModelTestsRecord, dir: &str, push: &mut impl FnMut(String), replan: &str) {
    if tests.selection == "paper" {
        push(format!(
            "let the calibration add the effects the data show: robimu calibrate {dir}"
        ));
        return;
    }
    let names: Vec<&str> = tests.significant.iter().map(|s| s.name.as_str()).collect();
    push(format!(
        "fit the effects the tests name and judge the result: robimu calibrate {dir} --effects {}",
        names.join(",")
    ));
    push(replan.to_string());
}
