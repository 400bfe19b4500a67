"""The reproductions of the third hostile pass, as cases for ``experiments/hostile_pass.py``.

Each case is the body of a function ``case()`` run in a fresh interpreter, in an empty working
folder, against one checkout (``REPO``). It ends by calling ``result(kind, note)`` with what
happened, or by raising: an ffsr-gym error (``FFSRError``) counts as a named error, anything else
as a raw traceback. ``kind`` is one of ``handled`` (what a careful user should get), ``named``
(refused by name, when refusing is right), ``code`` (code ran without consent), ``wrong`` (a
silently wrong result), ``loss`` (a result lost), and the harness adds ``hang`` (timed out) and
``crash`` (the process died).
"""

from __future__ import annotations

#: Helpers every case sees.
PREAMBLE = r'''
import json, os, sys, shutil, time, pathlib
import numpy as np
REPO = pathlib.Path(os.environ["HOSTILE_REPO"])
MARK = pathlib.Path("ran_code.marker").resolve()

def cli_main(argv):
    """``ffsr-gym`` of the checkout: ``ffsr_gym.cli.main`` (a package since the command line was split), or the
    older ``ffsr_gym.cli`` module."""
    import importlib
    try:
        module = importlib.import_module("ffsr_gym.cli.main")
    except ModuleNotFoundError:
        module = importlib.import_module("ffsr_gym.cli")
    return module.main(argv)

def result(kind, note=""):
    print("RESULT " + json.dumps({"class": kind, "note": str(note)[:300]}))
    sys.stdout.flush()
    os._exit(0)

def entry_json(env_id="FFSR-Residual-v2", indices=(0, 1)):
    import ffsr_gym
    act = (lambda o: 0.3 * np.sin(o[:12].astype(float))) if "Residual" in env_id else (lambda o: np.array([0.2, -0.3], "f4"))
    return ffsr_gym.evaluate(act, env_id, task="easy", indices=list(indices), name="mine").to_json()

def write(path, data):
    path = pathlib.Path(path); path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data) if not isinstance(data, str) else data)
    return path

def verify(path, *extra):
    return cli_main(["leaderboard", "verify", str(path), *extra])

def evil_module(name="evil"):
    pathlib.Path(f"{name}.py").write_text(f"open({str(MARK)!r}, 'w').write('x')\ndef act(o):\n    import numpy as np\n    return np.zeros(12, 'f4')\n")

def board():
    shutil.copytree(REPO / "leaderboards", "lb")
    return pathlib.Path("lb")

def forged(field_path, source="v2/easy/cmaes_v2.json", folder="v2/easy"):
    """Whether an entry whose text field (a path of keys) holds a newline and a table row forges a ranked row."""
    root = board(); e = json.loads((root / source).read_text()); target = e
    for key in field_path[:-1]:
        target = target.setdefault(key, {})
    target[field_path[-1]] = "x\n| 1 | `forged_winner` | 0.999 [0.999, 0.999] | 1.00 |"; e["name"] = "forge"
    write(root / folder / "forge.json", e)
    return any(l.startswith("| 1 | `forged_winner`") for l in readme_rows(root).splitlines())

def readme_rows(root):
    from ffsr_gym_lab.board import leaderboard
    leaderboard.write_readme(root)
    return (root / "README.md").read_text()

def summary(root):
    from ffsr_gym_lab.board import leaderboard
    return leaderboard.splice_summary((REPO / "README.md").read_text(), root)

def custom(old, new, extra=""):
    text = (REPO / "envs" / "scenarios" / "free_space.toml").read_text()
    for o, n in zip(old if isinstance(old, tuple) else (old,), new if isinstance(new, tuple) else (new,)):
        assert o in text, o
        text = text.replace(o, n)
    return str(write("custom.toml", text + extra))

def robot(urdf_old=None, urdf_new=None, coll_old=None, coll_new=None, coll_text=None):
    src = REPO / "envs" / "robots" / "ffsr_dual_arm"
    dst = pathlib.Path("bot"); dst.mkdir()
    urdf = (src / "ffsr_dual_arm.urdf").read_text()
    if urdf_old: assert urdf_old in urdf; urdf = urdf.replace(urdf_old, urdf_new, 1)
    (dst / "bot.urdf").write_text(urdf)
    coll = (src / "collision.toml").read_text() if coll_text is None else coll_text
    if coll_old: assert coll_old in coll; coll = coll.replace(coll_old, coll_new, 1)
    (dst / "collision.toml").write_text(coll)
    shutil.copytree(src / "drives", dst / "drives")
    return custom('robot = "ffsr_dual_arm"', 'robot = "./bot"')

def accepted_robot(**kw):
    from ffsr_gym.model.scenario import load_scenario
    import gymnasium as gym, ffsr_gym
    path = robot(**kw)
    load_scenario(path)
    gym.make("FFSR-v2", task=path).reset(seed=0)
    return path
'''

#: (id, defect number, what, body of ``case()``).
CASES: list[tuple[str, int, str, str]] = [
    ("verify-abs-file", 1, "an entry names /abs/evil.py:act", r'''
evil_module()
e = entry_json(); e["extra"]["policy"] = {"callable": str(pathlib.Path("evil.py").resolve()) + ":act"}
e["extra"].pop("trace", None)
verify(write("mine.json", e))
result("code" if MARK.exists() else "handled")'''),
    ("verify-rel-file", 1, "an entry names evil.py:act", r'''
evil_module()
e = entry_json(); e["extra"]["policy"] = {"callable": "evil.py:act"}; e["extra"].pop("trace", None)
verify(write("mine.json", e))
result("code" if MARK.exists() else "handled")'''),
    ("verify-module", 1, "an entry names a module in the working folder", r'''
evil_module("evilmod")
e = entry_json(); e["extra"]["policy"] = {"callable": "evilmod:act"}; e["extra"].pop("trace", None)
verify(write("mine.json", e))
result("code" if MARK.exists() else "handled")'''),
    ("verify-stdlib", 1, "an entry names os:getcwd", r'''
import os as _os
called = []
real = _os.getcwd
_os.getcwd = lambda *a: called.append(1) or real()
e = entry_json(); e["extra"]["policy"] = {"callable": "os:getcwd"}; e["extra"].pop("trace", None)
try:
    verify(write("mine.json", e))
except Exception:
    pass
result("code" if called else "handled")'''),
    ("verify-sb3-in-cwd", 2, "an entry names a model.zip a pull request ships", r'''
import base64, pickle, zipfile
class Evil:
    def __reduce__(self):
        return (open, (str(MARK), "w"))
data = {"policy_class": {":type:": "<class 'type'>", ":serialized:": base64.b64encode(pickle.dumps(Evil())).decode()}}
folder = pathlib.Path("leaderboards/v2/easy"); folder.mkdir(parents=True)
with zipfile.ZipFile(folder / "model.zip", "w") as z:
    z.writestr("data", json.dumps(data))
e = entry_json(); e["extra"]["policy"] = {"sb3": "leaderboards/v2/easy/model.zip", "algo": "ppo"}
e["extra"].pop("trace", None)
try:
    verify(write(folder / "mine.json", e))
except Exception:
    pass
result("code" if MARK.exists() else "handled")'''),
    ("evaluate-sb3-in-cwd", 2, "evaluate --policy model.zip in the working folder, no --trust-model", r'''
import base64, pickle, zipfile
class Evil:
    def __reduce__(self):
        return (open, (str(MARK), "w"))
data = {"policy_class": {":type:": "<class 'type'>", ":serialized:": base64.b64encode(pickle.dumps(Evil())).decode()}}
with zipfile.ZipFile("model.zip", "w") as z:
    z.writestr("data", json.dumps(data))
main = cli_main
main(["evaluate", "--env-id", "FFSR-v2", "--policy", "model.zip", "--algo", "ppo", "--no-progress"])
result("code" if MARK.exists() else "handled")'''),
    ("md-training-pool", 3, "a newline and | in extra.training_pool", r'''
result("wrong" if forged(["extra", "training_pool"]) else "handled")'''),
    ("md-commit", 3, "a newline and | in provenance.git_commit", r'''
result("wrong" if forged(["provenance", "git_commit"]) else "handled")'''),
    ("md-v0-method", 3, "a newline and | in a v0 entry's extra.method", r'''
source = sorted((REPO / "leaderboards/FFSR-v0").glob("*.json"))[0].name
result("wrong" if forged(["extra", "method"], f"FFSR-v0/{source}", "FFSR-v0") else "handled")'''),
    ("name-not-file", 4, "zzz.json named cmaes_residual", r'''
root = board(); before = summary(root)
e = json.loads((root / "v2/easy/random_residual.json").read_text()); e["name"] = "cmaes_residual"
write(root / "v2/easy/zzz.json", e)
result("wrong" if summary(root) != before else "handled")'''),
    ("name-suffix-collision", 4, "ppo_residual.json beside ppo_residual_easy.json", r'''
root = board(); before = summary(root)
e = json.loads((root / "v2/easy/ppo_residual_easy.json").read_text()); e["name"] = "ppo_residual"
write(root / "v2/easy/ppo_residual.json", e)
from ffsr_gym_lab.board import leaderboard
result("wrong" if summary(root) != before and not leaderboard.check(root) else "handled")'''),
    ("best-known-work", 5, "assemble from another work folder", r'''
from ffsr_gym_lab.best_known import build
shipped = REPO / "envs/benchmark/v2_best_known.json"; before = shipped.read_bytes()
build.run("easy", "test", "w", generations=1, indices=[0], progress=False)
build.assemble("w", generations=1, splits=["test"])
result("loss" if shipped.read_bytes() != before else "handled")'''),
    ("best-known-torn", 6, "resume after a torn last line", r'''
from ffsr_gym_lab.best_known import build
build.run("easy", "train", "w", generations=1, indices=[0], progress=False)
with open("w/easy_train.jsonl", "a") as f: f.write('{"tier": "easy", "spl')
build.run("easy", "train", "w", generations=1, indices=[0, 1], progress=False)
got = sorted(r["index"] for r in build.read_lines(pathlib.Path("w/easy_train.jsonl")))
result("handled" if got == [0, 1] else "loss", got)'''),
    ("best-known-budget", 6, "records of another generation budget", r'''
from ffsr_gym_lab.best_known import build
build.run("easy", "train", "w", generations=1, indices=[0], progress=False)
build.run("easy", "train", "w", generations=2, indices=[0], progress=False)
[out] = build.assemble("w", out="bk.json", generations=2)
n = len(json.loads(pathlib.Path(out).read_text())["tasks"].get("easy", {}).get("train", []))
result("handled" if n == 1 else "loss", n)'''),
    ("best-known-corrupt", 6, "work lines 42, \"hello\", {\"tier\": \"easy\"}", r'''
from ffsr_gym_lab.best_known import build
write("w/easy_train.jsonl", '42\n"hello"\n{"tier": "easy"}\n')
build.run("easy", "train", "w", generations=1, indices=[0], progress=False)
got = [r["index"] for r in build.read_lines(pathlib.Path("w/easy_train.jsonl"))]
result("handled" if got == [0] else "wrong", got)'''),
    ("dataset-failed-write", 7, "a dataset write that fails mid-way", r'''
import minari
from ffsr_gym_lab.publish import dataset
real = minari.create_dataset_from_buffers
def fail(*a, **k):
    real(*a, **k); raise OSError(28, "No space left on device")
minari.create_dataset_from_buffers = fail
try:
    dataset.write_dataset("easy", "FFSR-Residual-v2", root="ds")
except Exception:
    pass
os.environ["MINARI_DATASETS_PATH"] = str(pathlib.Path("ds").resolve())
result("wrong" if dataset.dataset_id("easy", "FFSR-Residual-v2") in minari.list_local_datasets() else "handled")'''),
    ("dataset-root-file", 7, "--root naming a file", r'''
pathlib.Path("afile").write_text("x")
from ffsr_gym_lab.publish import dataset
dataset.write_dataset("easy", "FFSR-Residual-v2", root="afile")
result("wrong")'''),
    ("length-make", 8, "a 40 s custom task through gymnasium.make", r'''
import gymnasium as gym, ffsr_gym
env = gym.make("FFSR-v2", task=custom("duration_s = 20.0", "duration_s = 40.0")); env.reset(seed=0)
n, done = 0, False
while not done:
    _, _, t, tr, info = env.step(np.array([0.2, -0.3], "f4")); n += 1; done = t or tr
result("handled" if n == 400 and "score" in info else "wrong", n)'''),
    ("length-callable", 8, "a 40 s custom task, a constant callable through evaluate", r'''
import ffsr_gym
task = custom("duration_s = 20.0", "duration_s = 40.0")
row = ffsr_gym.evaluate(lambda o: np.array([0.2, -0.3], "f4"), "FFSR-v2", task=task, seeds=[0]).episodes[0]
result("handled" if row["success"] else "wrong", row["failure"])'''),
    ("length-interval", 8, "decision_interval_s = 0.015", r'''
import gymnasium as gym, ffsr_gym
gym.make("FFSR-v2", task=custom("decision_interval_s = 0.1", "decision_interval_s = 0.015"))
result("wrong", "accepted")'''),
    ("length-duration", 8, "duration_s = 20.005", r'''
import gymnasium as gym, ffsr_gym
gym.make("FFSR-v2", task=custom("duration_s = 20.0", "duration_s = 20.005"))
result("wrong", "accepted")'''),
    ("length-scenario-task", 8, "evaluate --scenario X --task hard --split train", r'''
main = cli_main
rc = main(["evaluate", "--env-id", "FFSR-v2", "--policy", "0.3,4", "--scenario", custom("duration_s = 20.0",
           "duration_s = 20.0"), "--task", "hard", "--split", "train", "--no-progress"])
result("named" if rc == 2 else "wrong", rc)'''),
    ("robot-zero-axis", 9, "a joint axis 0 0 0", r'''
accepted_robot(urdf_old='<axis xyz="0 0 1"/>', urdf_new='<axis xyz="0 0 0"/>')
result("wrong", "accepted")'''),
    ("robot-fixed-negative-mass", 9, "a link on a fixed joint with mass -5", r'''
accepted_robot(urdf_old='<link name="mission_ee"/>', urdf_new='<link name="mission_ee"><inertial><mass value="-5"/>'
               '<inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>')
result("wrong", "accepted")'''),
    ("robot-fixed-inertia", 9, "a link on a fixed joint with a non-PD inertia", r'''
accepted_robot(urdf_old='<link name="balance_ee"/>', urdf_new='<link name="balance_ee"><inertial><mass value="1"/>'
               '<inertia ixx="-1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>')
result("wrong", "accepted")'''),
    ("robot-continuous", 9, "a continuous joint (the docs allow it)", r'''
accepted_robot(urdf_old='<joint name="mission_joint3" type="revolute">', urdf_new='<joint name="mission_joint3" type="continuous">')
result("handled")'''),
    ("collision-bool-radius", 9, "capsule_radius_m = true", r'''
accepted_robot(coll_old="capsule_radius_m = 0.02", coll_new="capsule_radius_m = true")
result("wrong", "accepted")'''),
    ("collision-text-radius", 9, "capsule_radius_m = \"0.02\"", r'''
accepted_robot(coll_old="capsule_radius_m = 0.02", coll_new='capsule_radius_m = "0.02"')
result("wrong", "accepted")'''),
    ("collision-ignored-text", 9, "ignored_pairs = \"ab\"", r'''
accepted_robot(coll_old='ignored_pairs = [["base", "mission_link1"], ["base", "balance_link1"]]', coll_new='ignored_pairs = "ab"')
result("wrong", "accepted")'''),
    ("collision-no-capsule", 9, "capsule = []", r'''
text = (REPO / "envs/robots/ffsr_dual_arm/collision.toml").read_text().split("[[capsule]]")[0]
accepted_robot(coll_text=text.replace("capsule_radius_m = 0.02", "capsule_radius_m = 0.02\ncapsule = []"))
result("wrong", "accepted")'''),
    ("urdf-fixed-chain", 10, "a chain of 4,500 fixed joints", r'''
links = "".join(f'<link name="x{k}"/><joint name="f{k}" type="fixed"><parent link="{"x" + str(k - 1) if k else "base"}"/><child link="x{k}"/></joint>' for k in range(4500))
accepted_robot(urdf_old="</robot>", urdf_new=links + "</robot>")
result("handled", "loaded")'''),
    ("urdf-star", 10, "10^5 fixed links in a star", r'''
links = "".join(f'<link name="x{k}"/><joint name="f{k}" type="fixed"><parent link="base"/><child link="x{k}"/></joint>' for k in range(100000))
accepted_robot(urdf_old="</robot>", urdf_new=links + "</robot>")
result("handled", "loaded")'''),
    ("memory-pool-dt", 11, "dt_s = 1e-5 on a pool", r'''
import ffsr_gym
ffsr_gym.evaluate((0.3, 4.0), "FFSR-v2", task="easy", env_kwargs={"dt_s": 1e-5})
result("handled")'''),
    ("memory-hour", 11, "duration_s = 3600 with dt_s = 1e-5", r'''
import gymnasium as gym, ffsr_gym
gym.make("FFSR-v2", task=custom(("duration_s = 20.0", "dt_s = 0.01"), ("duration_s = 3600.0", "dt_s = 0.00001"))).reset(seed=0)
result("handled")'''),
    ("memory-copies", 11, "BatchedVecEnv with a million copies", r'''
from ffsr_gym.environments.sb3_vec_env import BatchedVecEnv
BatchedVecEnv("FFSR-v2", 1_000_000, task="easy")
result("handled")'''),
    ("hang-fifo", 12, "a FIFO named *.json in a tier folder", r'''
root = board(); os.mkfifo(root / "v2/easy/fifo.json")
from ffsr_gym_lab.board import leaderboard
problems = leaderboard.check(root)
result("named" if problems else "wrong")'''),
    ("hang-render-mode", 12, "an entry with render_mode human", r'''
e = entry_json(); e["env_kwargs"]["render_mode"] = "human"
from ffsr_gym.environments.env import FFSREnv
drawn = []
FFSREnv.render = lambda self: drawn.append(1)
verify(write("mine.json", e))
result("wrong" if drawn else "handled", len(drawn))'''),
    ("hang-repeat", 12, "an entry repeating task_index 0 twenty thousand times", r'''
e = entry_json(indices=(0,)); e["episodes"] = e["episodes"] * 20000
e["extra"].pop("trace", None); e["extra"]["policy"] = {"fixed": [0.0] * 12}
result("named" if verify(write("mine.json", e)) == 2 else "wrong", "played")'''),
    ("hang-servo", 12, "servo physics_step_s = 1e-6 with a 600 s decision", r'''
import gymnasium as gym, ffsr_gym
task = custom(("decision_interval_s = 0.1", "duration_s = 20.0", "[simulation]"),
              ("decision_interval_s = 600.0", "duration_s = 600.0", '[simulation]\nplant = "servo"'),
              "\n[servo]\nphysics_step_s = 0.000001\n")
env = gym.make("FFSR-v2", task=task); env.reset(seed=0); env.step(np.zeros(2, "f4"))
result("handled")'''),
    ("raw-extra-5", 13, "verify of \"extra\": 5", r'''
e = entry_json(); e["extra"] = 5
result("named" if verify(write("mine.json", e)) == 2 else "wrong")'''),
    ("raw-fixed-5", 13, "verify of \"policy\": {\"fixed\": 5}", r'''
e = entry_json(); e["extra"]["policy"] = {"fixed": 5}; e["extra"].pop("trace", None)
result("named" if verify(write("mine.json", e)) == 2 else "wrong")'''),
    ("raw-no-task", 13, "verify of env_kwargs without task", r'''
e = entry_json(); e["env_kwargs"].pop("task")
result("named" if verify(write("mine.json", e)) == 2 else "wrong")'''),
    ("raw-planner", 13, "verify of \"planner\": {}", r'''
e = entry_json(); e["extra"]["planner"] = {}
result("named" if verify(write("mine.json", e)) == 2 else "wrong")'''),
    ("raw-episodes", 13, "verify of \"episodes\": {\"a\": 1}", r'''
e = entry_json(); e["episodes"] = {"a": 1}
result("named" if verify(write("mine.json", e)) == 2 else "wrong")'''),
    ("raw-deep-json", 13, "verify of a 100,000-deep JSON array", r'''
e = entry_json(); e["deep"] = None
write("mine.json", json.dumps(e).replace('"deep": null', '"deep": ' + "[" * 100000 + "]" * 100000))
result("named" if verify("mine.json") == 2 else "wrong")'''),
    ("raw-deep-toml", 13, "a scenario TOML nested 100,000 deep", r'''
from ffsr_gym.model.scenario import load_scenario
load_scenario(custom("duration_s = 20.0", "duration_s = 20.0", "x = " + "[" * 100000 + "]" * 100000 + "\n"))
result("wrong")'''),
    ("raw-render-speed", 13, "render --speed 1e-300", r'''
main = cli_main
rc = main(["render", "--env-id", "FFSR-v2", "--speed", "1e-300", "--out", "x.gif"])
result("named" if rc == 2 else "wrong", rc)'''),
    ("raw-render-out", 13, "render --out /bin/ls/x.gif", r'''
main = cli_main
rc = main(["render", "--env-id", "FFSR-v2", "--out", "/bin/ls/x.gif"])
result("named" if rc == 2 else "wrong", rc)'''),
    ("raw-workers-pickle", 13, "evaluate --policy mine.py:act --workers 2", r'''
pathlib.Path("mine.py").write_text("import numpy as np\ndef act(o):\n    return np.zeros(2, 'f4')\n")
main = cli_main
rc = main(["evaluate", "--env-id", "FFSR-v2", "--policy", "mine.py:act", "--workers", "2", "--no-progress"])
result("named" if rc == 2 else "wrong", rc)'''),
    ("raw-algo-mismatch", 13, "--policy ppo.zip --algo sac", r'''
import gymnasium as gym, ffsr_gym
from stable_baselines3 import PPO
PPO("MlpPolicy", gym.make("FFSR-v2"), n_steps=64, batch_size=64, device="cpu").save("ppo.zip")
main = cli_main
rc = main(["evaluate", "--env-id", "FFSR-v2", "--policy", "ppo.zip", "--algo", "sac", "--trust-model", "--no-progress"])
result("named" if rc == 2 else "wrong", rc)'''),
    ("raw-threads-text", 13, "BatchedVecEnv(threads=\"1\")", r'''
from ffsr_gym.environments.sb3_vec_env import BatchedVecEnv
BatchedVecEnv("FFSR-v2", 2, threads="1", task="easy"); result("wrong")'''),
    ("raw-threads-float", 13, "BatchedVecEnv(threads=1.5)", r'''
from ffsr_gym.environments.sb3_vec_env import BatchedVecEnv
BatchedVecEnv("FFSR-v2", 2, threads=1.5, task="easy"); result("wrong")'''),
    ("raw-seed-text", 13, "BatchedVecEnv.seed(\"3\")", r'''
from ffsr_gym.environments.sb3_vec_env import BatchedVecEnv
BatchedVecEnv("FFSR-v2", 2, task="easy").seed("3"); result("wrong")'''),
    ("raw-step-none", 13, "BatchedVecEnv.step_async(None)", r'''
from ffsr_gym.environments.sb3_vec_env import BatchedVecEnv
env = BatchedVecEnv("FFSR-v2", 2, task="easy"); env.reset(); env.step_async(None); env.step_wait(); result("wrong")'''),
    ("raw-full-disk", 13, "an entry saved on a full disk", r'''
import ffsr_gym
report = ffsr_gym.evaluate((0.3, 4.0), "FFSR-v2", task="easy", indices=[0], name="mine")
path = report.save("out"); before = path.read_bytes()
def full(*a):
    raise OSError(28, "No space left on device")
os.replace = full
import inspect
again = {"overwrite": True} if "overwrite" in inspect.signature(report.save).parameters else {}
try:
    report.save("out", **again)
finally:
    if path.read_bytes() != before:
        result("loss")'''),
    ("silent-residual-no", 14, "gymnasium.make(\"FFSR-v2\", residual=\"no\")", r'''
import gymnasium as gym, ffsr_gym
env = gym.make("FFSR-v2", residual="no")
result("wrong" if env.action_space.shape == (12,) else "handled")'''),
]
