"""The Python API against the `robimu` program on the same session.

The program is `$ROBIMU_CLI` when set (e.g. target/debug/robimu), else the
`robimu` command the wheel installs."""

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import robimu

CLI = os.environ.get("ROBIMU_CLI") or shutil.which("robimu")
PATH_KEYS = {"session"}


def cli(*args):
    assert CLI, "no robimu program: set ROBIMU_CLI or install the wheel"
    return subprocess.run([CLI, *map(str, args)], capture_output=True, text=True)


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    d = tmp_path_factory.mktemp("sim") / "session"
    s = robimu.simulate("aubo_i5", duration=60, seed=3, out=d)
    return d, s


def without_paths(path):
    lines = Path(path).read_text().splitlines()
    return [l for l in lines if l.strip().split(":")[0].strip('"') not in PATH_KEYS]


def test_simulate_matches_cli(sim, tmp_path):
    d, s = sim
    r = cli("simulate", "--robot", "aubo_i5", "--duration", "60", "--seed", "3", "--out", tmp_path / "c")
    assert r.returncode == 0, r.stderr
    for f in ["session.toml", "joints.csv", "imu.csv", "truth.toml"]:
        assert (tmp_path / "c" / f).read_bytes() == (d / f).read_bytes(), f
    assert s.truth and "tau" in s.truth


def test_calibrate_matches_cli_bit_for_bit(sim, tmp_path):
    d, s = sim
    r = robimu.calibrate(s)
    r.save(tmp_path / "py.json")
    c = cli("calibrate", d, "--out", tmp_path / "cli.json")
    assert c.returncode == 0, c.stderr
    assert without_paths(tmp_path / "py.json") == without_paths(tmp_path / "cli.json")
    assert (tmp_path / "py.convergence.csv").read_bytes() == (tmp_path / "cli.convergence.csv").read_bytes()
    # the API's view of the same file
    data = json.loads((tmp_path / "cli.json").read_text())
    assert r.verdict.trust == data["verdict"]["trust"]
    assert list(r.parameters) == [p["name"] for p in data["parameters"]]
    assert r.covariance.shape == (len(r.covariance_names),) * 2
    assert np.array_equal(r.covariance, np.array(data["covariance"]["matrix"]))
    again = robimu.Result.load(tmp_path / "cli.json")
    assert again.to_dict() == data


def test_calibrate_options_match_cli(sim, tmp_path):
    d, s = sim
    robimu.calibrate(s, model="paper", freeze="lengths", noise_model="white", out=tmp_path / "py.json")
    c = cli("calibrate", d, "--model", "paper", "--freeze", "lengths", "--noise-model", "white",
            "--out", tmp_path / "cli.json")
    assert c.returncode == 0, c.stderr
    assert without_paths(tmp_path / "py.json") == without_paths(tmp_path / "cli.json")


def test_session_arrays_and_save(sim, tmp_path):
    d, s = sim
    assert s.joints.shape == (len(s.joint_t), s.dof)
    imu = s.imu()
    assert imu.accel.shape == (len(imu.t), 3) and imu.gyro.shape == (len(imu.t), 3)
    rows = np.loadtxt(d / "imu.csv", delimiter=",", skiprows=1)
    assert np.array_equal(rows[:, 0], imu.t)
    s.save(tmp_path / "copy")
    for f in ["session.toml", "joints.csv", "imu.csv", "truth.toml"]:
        assert (tmp_path / "copy" / f).read_bytes() == (d / f).read_bytes()


def test_check(sim):
    d, s = sim
    rep = robimu.check(s)
    assert rep.ok and rep.fatal is None
    c = cli("check", d)
    assert c.returncode == 0


def test_bad_input_raises_with_the_cli_message(tmp_path):
    with pytest.raises(robimu.BadInputError) as e:
        robimu.Session.load(tmp_path / "missing")
    c = cli("calibrate", tmp_path / "missing")
    assert c.returncode == 1
    assert str(e.value).splitlines()[0] in c.stderr
    with pytest.raises(robimu.BadInputError, match="--model `nope`"):
        robimu.calibrate(robimu.simulate(duration=10, seed=1), model="nope")
    with pytest.raises(robimu.BadInputError, match="unknown robot"):
        robimu.simulate("no_such_robot", duration=10)
    assert issubclass(robimu.NotConvergedError, robimu.RobimuError)


def test_robots_match_cli():
    names = [r.name for r in robimu.robots()]
    out = cli("robots").stdout
    assert names and all(n in out for n in names)


def same_files(a, b, names):
    for f in names:
        assert (Path(a) / f).read_bytes() == (Path(b) / f).read_bytes(), f


def test_plan_matches_cli(tmp_path):
    p = robimu.plan(tmp_path / "py", duration=10, evaluations=20, seed=2)
    assert p.path == tmp_path / "py" and "plan" in str(p).lower()
    c = cli("plan", "--duration", "10", "--evaluations", "20", "--seed", "2", "--out", tmp_path / "cli")
    assert c.returncode == 0, c.stderr
    same_files(tmp_path / "py", tmp_path / "cli", ["plan.csv", "spline.toml", "identifiability.csv", "sigma.csv"])
    # the plan drives a simulation
    s = robimu.simulate(trajectory=p.path, seed=1)
    assert s.joint_t[-1] > 9


def test_diagnose_matches_cli(sim, tmp_path):
    d, s = sim
    dg = robimu.diagnose(s, out=tmp_path / "py", candidates="joint_elasticity,bias_drift")
    c = cli("diagnose", d, "--out", tmp_path / "cli", "--candidates", "joint_elasticity,bias_drift")
    assert c.returncode == 0, c.stderr
    assert without_paths(tmp_path / "py" / "diagnosis.json") == without_paths(tmp_path / "cli" / "diagnosis.json")
    assert dg.path == tmp_path / "py" / "diagnosis.json"
    assert dg.data == json.loads((tmp_path / "py" / "diagnosis.json").read_text())


@pytest.fixture(scope="module")
def paper_result(sim, tmp_path_factory):
    """One calibration (the paper's model) of the module's session, saved."""
    d, s = sim
    path = tmp_path_factory.mktemp("paper") / "result.json"
    return robimu.calibrate(s, model="paper", out=path), path


@pytest.mark.parametrize("fmt,name", [("urdf", "robot.urdf"), ("toml", "robot.toml"),
                                      ("kalibr", "imu.yaml"), ("correction", "correction.toml"),
                                      ("ros2-control", "offsets.xml")])
def test_export_matches_cli(paper_result, tmp_path, fmt, name):
    r, result = paper_result
    (tmp_path / "py").mkdir()
    (tmp_path / "cli").mkdir()
    wrote = robimu.export(r, fmt, tmp_path / "py" / name)
    assert tmp_path / "py" / name in wrote
    c = cli("export", "--calibration", result, "--format", fmt, "--out", tmp_path / "cli" / name)
    assert c.returncode == 0, c.stderr
    assert (tmp_path / "py" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes()


def test_export_refuses_a_robot_of_another_structure(sim, paper_result, tmp_path):
    d, s = sim
    r, _ = paper_result
    with pytest.raises(robimu.RobimuError):
        robimu.export(r, "ur-kinematics", tmp_path / "k.yaml")
    c = cli("export", "--calibration", d / "nope.json", "--format", "urdf", "--out", tmp_path / "x.urdf")
    assert c.returncode == 1
    with pytest.raises(robimu.BadInputError) as e:
        robimu.export(d / "nope.json", "urdf", tmp_path / "x.urdf")
    assert str(e.value).splitlines()[0] in c.stderr


def test_two_imus_each_with_its_noise_model():
    s = robimu.simulate("aubo_i5", duration=30, seed=2, imus=2)
    assert s.n_imus == 2 and s.imu(1).accel.shape[1] == 3
    r = robimu.calibrate(s, model="paper")
    assert [m["imu"] for m in r.imu_noise_models] == ["imu1"]
    assert "imu1/tau" in r.parameters and r.noise_model is not None
