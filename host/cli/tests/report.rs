//! The HTML reports: written by the CLI, self-contained, and rendered by a
//! real browser (headless Chromium) without console errors, with the tables
//! and figures in the DOM.

use std::path::{Path, PathBuf};
use std::process::Command;

mod common;
use common::{assert_figure_glyphs, robimu, robimu_ok};

/// Headless Chromium, or `None` when it is not installed. In CI (env `CI`
/// set) a missing browser is a failure, not a skip.
fn chromium() -> Option<PathBuf> {
    let candidates = std::env::var("ROBIMU_CHROMIUM")
        .into_iter()
        .chain(["chromium", "chromium-browser", "google-chrome"].map(String::from));
    for c in candidates {
        if let Ok(out) = Command::new(&c).arg("--version").output() {
            if out.status.success() {
                return Some(PathBuf::from(c));
            }
        }
    }
    if std::env::var_os("CI").is_some() {
        panic!("headless Chromium is required in CI (apt-get install chromium)");
    }
    eprintln!("chromium is not installed: the browser rendering check is skipped (it is required when CI is set)");
    None
}

/// Render `page` in headless Chromium: (DOM after load, browser log).
fn render(browser: &Path, page: &Path, profile: &Path) -> (String, String) {
    render_with(browser, page, profile, &[])
}

/// [`render`] with extra Chromium arguments.
fn render_with(browser: &Path, page: &Path, profile: &Path, extra: &[&str]) -> (String, String) {
    let url = format!("file://{}", page.canonicalize().unwrap().display());
    let out = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-background-networking",
            "--enable-logging=stderr",
            "--v=0",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .args(extra)
        .args(["--dump-dom", &url])
        .output()
        .expect("run chromium");
    assert!(out.status.success(), "chromium failed: {:?}", out);
    (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// No scripts, no stylesheets or images from elsewhere.
fn assert_self_contained(html: &str) {
    let lower = html.to_lowercase();
    for bad in [
        "<script",
        "<link",
        "<img src=\"http",
        "src=\"http",
        "href=\"http",
        "url(http",
        "@import",
    ] {
        assert!(!lower.contains(bad), "the page contains `{bad}`");
    }
}

fn assert_renders(browser: Option<&Path>, page: &Path, must_contain: &[&str]) {
    let html = std::fs::read_to_string(page).unwrap();
    assert_self_contained(&html);
    for m in must_contain {
        assert!(html.contains(m), "{} lacks {m}", page.display());
    }
    let Some(browser) = browser else { return };
    let profile = tempfile::tempdir().unwrap();
    let (dom, log) = render(browser, page, profile.path());
    for m in must_contain {
        assert!(
            dom.contains(m),
            "the rendered DOM of {} lacks {m}",
            page.display()
        );
    }
    assert!(dom.contains("<svg"), "no inline figure in the DOM");
    let console_errors: Vec<&str> = log
        .lines()
        .filter(|l| {
            l.contains("CONSOLE") || l.contains("Uncaught") || l.contains("ERR_FILE_NOT_FOUND")
        })
        .collect();
    assert!(
        console_errors.is_empty(),
        "browser console: {console_errors:#?}"
    );
}

/// Written into a test copy of a page (the page itself has no scripts):
/// records errors (script, console.error, resources that fail to load),
/// and after the load event writes them, every `<img>`'s natural size and
/// every inline `<svg>`'s rendered size into `<pre id="render-check">` as
/// JSON, which `--dump-dom` returns.
const RENDER_CHECK: &str = r#"<script>
window.__errors = [];
window.addEventListener('error', function (e) {
  var t = e.target;
  window.__errors.push(t && t.tagName ? 'cannot load ' + t.tagName + ' ' + (t.currentSrc || t.src) : String(e.message));
}, true);
var consoleError = console.error;
console.error = function () { window.__errors.push(Array.from(arguments).join(' ')); consoleError.apply(console, arguments); };
window.addEventListener('load', function () {
  var images = Array.from(document.images).map(function (i) { return [i.getAttribute('src'), i.naturalWidth, i.naturalHeight]; });
  var svgs = Array.from(document.querySelectorAll('body > figure > svg')).map(function (s) { var r = s.getBoundingClientRect(); return [r.width, r.height]; });
  var out = document.createElement('pre');
  out.id = 'render-check';
  var t = document.getElementById('trust');
  var trust = t ? [t.textContent, t.getBoundingClientRect().height] : null;
  out.textContent = JSON.stringify({errors: window.__errors, images: images, svgs: svgs, trust: trust});
  document.body.appendChild(out);
});
</script>"#;

/// (width, height) from a PNG's IHDR chunk.
fn png_size(path: &Path) -> (u64, u64) {
    let b = std::fs::read(path).unwrap();
    assert_eq!(&b[..8], b"\x89PNG\r\n\x1a\n", "{}", path.display());
    let be = |o: usize| u32::from_be_bytes(b[o..o + 4].try_into().unwrap()) as u64;
    (be(16), be(20))
}

/// The [`RENDER_CHECK`] result of `page` in Chromium: a test copy of it
/// (next to it, so relative paths resolve) with the check and an `<img>`
/// per name in `images` appended.
fn render_check(browser: &Path, page: &Path, images: &[String]) -> serde_json::Value {
    let dir = page.parent().unwrap();
    let html = std::fs::read_to_string(page).unwrap();
    let imgs: String = images
        .iter()
        .map(|p| format!("<img src=\"{p}\" alt=\"{p}\">"))
        .collect();
    let copy = html
        .replacen("<head>", &format!("<head>{RENDER_CHECK}"), 1)
        .replacen("</body>", &format!("{imgs}</body>"), 1);
    let test_page = dir.join("render-check.html");
    std::fs::write(&test_page, copy).unwrap();
    let profile = tempfile::tempdir().unwrap();
    let (dom, log) = render_with(
        browser,
        &test_page,
        profile.path(),
        &[
            "--allow-file-access-from-files",
            "--virtual-time-budget=10000",
        ],
    );
    std::fs::remove_file(&test_page).unwrap();
    let tag = "<pre id=\"render-check\">";
    let start = dom
        .find(tag)
        .unwrap_or_else(|| panic!("the check did not run on {}: {log}", page.display()));
    let body = &dom[start + tag.len()..];
    let json = body[..body.find("</pre>").unwrap()]
        .replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&amp;", "&");
    serde_json::from_str(&json).unwrap()
}

/// `page` in Chromium with every figure of its directory as an `<img>`
/// ([`render_check`]): no errors; each image loads at the PNG's own size
/// (naturalWidth > 0); each inline SVG figure (one per `*.svg` file) is
/// laid out with a non-zero size.
fn assert_figures_load(browser: &Path, page: &Path) {
    let dir = page.parent().unwrap();
    let files: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    let mut pngs: Vec<String> = files
        .iter()
        .filter(|n| n.ends_with(".png"))
        .cloned()
        .collect();
    pngs.sort();
    let svgs = files.iter().filter(|n| n.ends_with(".svg")).count();
    assert!(!pngs.is_empty() && svgs > 0, "{}", dir.display());
    let check = render_check(browser, page, &pngs);
    eprintln!("{}: {check}", page.display());
    assert_eq!(check["errors"], serde_json::json!([]), "{}", page.display());
    let images = check["images"].as_array().unwrap();
    assert_eq!(images.len(), pngs.len(), "{check}");
    for (img, name) in images.iter().zip(&pngs) {
        assert_eq!(img[0], name.as_str());
        let (w, h) = png_size(&dir.join(name));
        assert!(w > 0 && h > 0);
        assert_eq!(
            (img[1].as_u64(), img[2].as_u64()),
            (Some(w), Some(h)),
            "{name}"
        );
    }
    // the verdict's trust line, where the page has one, is laid out
    if std::fs::read_to_string(page)
        .unwrap()
        .contains("<p id=\"trust\"")
    {
        let trust = &check["trust"];
        assert!(
            trust[0].as_str().unwrap().starts_with("trust: ") && trust[1].as_f64().unwrap() > 5.0,
            "{check}"
        );
    }
    let figures = check["svgs"].as_array().unwrap();
    assert_eq!(
        figures.len(),
        svgs,
        "one inline figure per SVG file: {check}"
    );
    for f in figures {
        assert!(
            f[0].as_f64().unwrap() > 100.0 && f[1].as_f64().unwrap() > 100.0,
            "{check}"
        );
    }
}

/// The check sees a failure: an image that does not load is an error and
/// has naturalWidth 0.
fn assert_render_check_sees_a_missing_image(browser: &Path, page: &Path) {
    let check = render_check(browser, page, &["missing.png".into()]);
    let errors = check["errors"].as_array().unwrap();
    assert!(
        errors.len() == 1 && errors[0].as_str().unwrap().contains("missing.png"),
        "{check}"
    );
    assert_eq!(check["images"][0][1], 0, "{check}");
}

#[test]
fn cli_reports_render_in_headless_chromium() {
    let dir = tempfile::tempdir().unwrap();
    let s = dir.path().join("s");
    let s = s.to_str().unwrap();
    robimu_ok(&[
        "simulate",
        "--duration",
        "60",
        "--tracker",
        "--poses",
        "60",
        "--seed",
        "9",
        "--out",
        s,
    ]);
    let rep = dir.path().join("rep");
    robimu_ok(&[
        "calibrate",
        s,
        "--freeze",
        "lengths",
        "--report",
        rep.to_str().unwrap(),
    ]);
    let result = format!("{s}/result.json");
    let text = robimu_ok(&[
        "validate",
        s,
        "--calibration",
        &result,
        "--tracker",
        &format!("{s}/poses.csv"),
    ])
    .stdout;
    assert!(
        text.contains("robot accuracy on 24 held-out poses"),
        "{text}"
    );
    assert!(text.contains("IMU accuracy"), "{text}");
    let out2 = dir.path().join("rep2");
    robimu_ok(&["report", &result, "--out", out2.to_str().unwrap()]);
    check_convergence_history(Path::new(&result), &out2);
    // a result without its iteration history: the page says why
    let bare = dir.path().join("bare");
    std::fs::create_dir_all(&bare).unwrap();
    std::fs::copy(&result, bare.join("result.json")).unwrap();
    let out3 = dir.path().join("rep3");
    robimu_ok(&[
        "report",
        bare.join("result.json").to_str().unwrap(),
        "--out",
        out3.to_str().unwrap(),
    ]);
    let page3 = std::fs::read_to_string(out3.join("report.html")).unwrap();
    assert!(
        page3.contains("No convergence figure") && page3.contains("result.convergence.csv"),
        "{page3}"
    );
    assert!(!out3.join("convergence.svg").exists());
    check_tracker_offset(Path::new(s), dir.path(), &result);

    let browser = chromium();
    let b = browser.as_deref();
    for (page, marks) in [
        (
            rep.join("report.html"),
            &[
                "<p id=\"trust\"",
                "<table id=\"verdict\"",
                "<table id=\"parameters\"",
                "eps_2_4",
                "Convergence",
                "Residuals",
            ][..],
        ),
        (
            out2.join("report.html"),
            &[
                "<p id=\"trust\"",
                "<table id=\"parameters\"",
                "eps_2_4",
                "Trajectory",
                "cost at each iteration.",
            ][..],
        ),
        (
            Path::new(s).join("validation/validation.html"),
            &[
                "<table id=\"robot-accuracy\"",
                "<table id=\"imu-accuracy\"",
                "classical (tracker)",
            ][..],
        ),
    ] {
        assert_renders(b, &page, marks);
        let strings = assert_figure_glyphs(page.parent().unwrap());
        eprintln!("{}: {strings} figure strings have glyphs", page.display());
        if let Some(b) = b {
            assert_figures_load(b, &page);
        }
    }
    if let Some(b) = b {
        assert_render_check_sees_a_missing_image(b, &rep.join("report.html"));
    }
    // the figures read at a glance: σ reduction by parameter name in
    // groups, residuals with the noise band, τ in ms
    let sigma = std::fs::read_to_string(rep.join("posterior_sigma.svg")).unwrap();
    for name in [
        "eps_2_4",
        "gamma_a_yz",
        "b_w_z",
        "tau",
        "accelerometer",
        "frozen",
    ] {
        assert!(sigma.contains(&format!(">\n{name}\n<")), "{name}");
    }
    let residuals = std::fs::read_to_string(rep.join("residuals.svg")).unwrap();
    assert!(residuals.contains("±1σ noise") && residuals.contains(" ms)"));
    let page = std::fs::read_to_string(rep.join("report.html")).unwrap();
    assert!(
        page.contains("<td>tau</td><td>ms</td>"),
        "τ in ms in the table"
    );
    for f in [
        "robot_accuracy.png",
        "robot_accuracy.svg",
        "imu_accuracy.png",
    ] {
        assert!(Path::new(s).join("validation").join(f).is_file(), "{f}");
    }
    for f in [
        "residuals.png",
        "convergence.svg",
        "trajectory.png",
        "posterior_sigma.svg",
    ] {
        assert!(rep.join(f).is_file(), "{f}");
    }
}

/// A calibration whose model gained an effect (a 100 ms accelerometer
/// delay the paper's model lacks): its page shows the pose accuracy, the
/// model with the effect's test and parameters, and the residuals and
/// their spectra before and after, every figure loading in Chromium.
#[test]
fn a_calibration_with_an_effect_shows_the_evidence_before_and_after() {
    let dir = tempfile::tempdir().unwrap();
    let s = dir.path().join("s");
    let s = s.to_str().unwrap();
    robimu_ok(&[
        "simulate",
        "--duration",
        "40",
        "--seed",
        "5",
        "--effect",
        "sensor_delay=100",
        "--out",
        s,
    ]);
    let rep = dir.path().join("rep");
    let run = robimu_ok(&["calibrate", s, "--report", rep.to_str().unwrap()]);
    assert!(
        run.stdout.contains("model: the paper's + sensor_delay"),
        "{}",
        run.stdout
    );
    let page = rep.join("report.html");
    let marks = [
        "<table id=\"pose-accuracy\"",
        "<table id=\"effects\"",
        "<table id=\"effect-parameters\"",
        "sensor_delay",
        "RMS over time before",
        "spectra before and after the effects",
    ];
    let browser = chromium();
    assert_renders(browser.as_deref(), &page, &marks);
    for f in ["model_residuals.svg", "model_spectra.svg", "residuals.svg"] {
        assert!(rep.join(f).is_file(), "{f}");
    }
    assert_figure_glyphs(&rep);
    if let Some(b) = browser.as_deref() {
        assert_figures_load(b, &page);
    }
    // exports and corrections take the final model and say what they
    // cannot carry of it
    let result = format!("{s}/result.json");
    let robot = dir.path().join("robot.toml");
    let run = robimu_ok(&[
        "export",
        "--calibration",
        &result,
        "--format",
        "toml",
        "--out",
        robot.to_str().unwrap(),
    ]);
    assert!(
        run.stderr.contains("includes sensor_delay")
            && run.stderr.contains("a robot TOML cannot carry"),
        "{}",
        run.stderr
    );
    let run = robimu_ok(&["correct", "--calibration", &result, &format!("{s}/imu.csv")]);
    assert!(
        run.stderr.contains("includes sensor_delay"),
        "{}",
        run.stderr
    );
}

#[test]
fn validate_rejects_bad_inputs_with_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let s = dir.path().join("s");
    let s = s.to_str().unwrap();
    robimu_ok(&["simulate", "--duration", "20", "--out", s]);
    let poses = dir.path().join("poses.csv");
    std::fs::write(&poses, "t,px,py,pz,qw,qx,qy,qz\n0,0,0,0,0,0,0,0\n").unwrap();
    let out = robimu([
        "validate",
        s,
        "--calibration",
        &format!("{s}/nope.json"),
        "--tracker",
        poses.to_str().unwrap(),
    ]);
    assert!(!out.success());
    let err = &out.stderr;
    assert!(err.contains("nope.json"), "{err}");
    let out = robimu(["report", &format!("{s}/missing.json")]);
    assert!(!out.success());
    assert!(out.stderr.contains("missing.json"));
}

/// `calibrate` wrote result.convergence.csv: its costs decrease (LM accepts
/// only decreasing steps) and its last one is the result's final cost; the
/// page of `robimu report RESULT` draws it.
fn check_convergence_history(result: &Path, out: &Path) {
    let csv = result.with_file_name("result.convergence.csv");
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("iteration,cost,step_norm,lambda,gradient_norm,tries")
    );
    let costs: Vec<f64> = lines
        .map(|l| l.split(',').nth(1).unwrap().parse().unwrap())
        .collect();
    assert!(costs.len() >= 3, "{text}");
    for w in costs.windows(2) {
        assert!(w[1] <= w[0] * (1.0 + 1e-12), "cost rose: {costs:?}");
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(result).unwrap()).unwrap();
    let final_cost = json["final_cost"].as_f64().unwrap();
    let last = *costs.last().unwrap();
    eprintln!(
        "convergence: {} rows, cost {} -> {last}, result final_cost {final_cost}",
        costs.len(),
        costs[0]
    );
    assert!(
        (last - final_cost).abs() <= 1e-6 * final_cost.abs(),
        "last {last} vs final {final_cost}"
    );
    assert_eq!(
        json["iterations"].as_u64().unwrap() as usize,
        costs.len() - 1
    );
    assert!(out.join("convergence.svg").is_file());
    let page = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(!page.contains("No convergence figure"));
}

/// A tracked motion whose tracker clock runs 0.137 s ahead of the session's:
/// `validate` finds δ within 2 ms, reports it (stdout, validation.json,
/// validation.html), takes it from --tracker-offset, and refuses an offset
/// that leaves no overlap.
fn check_tracker_offset(session: &Path, tmp: &Path, result: &str) {
    let motion = tmp.join("shifted");
    std::fs::create_dir_all(&motion).unwrap();
    for f in ["session.toml", "joints.csv", "imu.csv"] {
        std::fs::copy(session.join(f), motion.join(f)).unwrap();
    }
    let text = std::fs::read_to_string(session.join("tracker.csv")).unwrap();
    let mut shifted = String::new();
    for (k, line) in text.lines().enumerate() {
        if k == 0 || line.starts_with('#') {
            shifted.push_str(line);
        } else {
            let (t, rest) = line.split_once(',').unwrap();
            let t: f64 = t.parse().unwrap();
            shifted.push_str(&format!("{},{rest}", t + 0.137));
        }
        shifted.push('\n');
    }
    std::fs::write(motion.join("tracker.csv"), shifted).unwrap();
    let poses = session.join("poses.csv");
    let report = tmp.join("val-shifted");
    let base = [
        "validate",
        session.to_str().unwrap(),
        "--calibration",
        result,
        "--tracker",
        poses.to_str().unwrap(),
        "--motion",
        motion.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ];
    let text = robimu_ok(&base).stdout;
    eprintln!("{text}");
    assert!(text.contains("estimated by matching"), "{text}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(report.join("validation.json")).unwrap())
            .unwrap();
    let ms = json["tracker_offset"]["delta_ms"].as_f64().unwrap();
    assert!((ms - 137.0).abs() < 2.0, "delta {ms} ms");
    assert!(json["imu_accuracy"]["calibrated"]["rms_gyro_deg_s"].is_f64());
    let page = std::fs::read_to_string(report.join("validation.html")).unwrap();
    assert!(page.contains("Tracker time offset"));

    let given = robimu_ok(&[&base[..], &["--tracker-offset", "0.137"]].concat()).stdout;
    assert!(given.contains("137.0 ms (given)"), "{given}");
    let out = robimu([&base[..], &["--tracker-offset", "-500"]].concat());
    assert!(!out.success());
    let err = &out.stderr;
    assert!(
        err.contains("does not overlap") && err.contains("tracker.csv"),
        "{err}"
    );
}
