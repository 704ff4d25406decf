"""Every example a user can copy runs: each command's ``--help`` Example block and the code blocks of the README
and of the docs site's Markdown pages (``docs/**/*.md``).

The examples are read from where users read them (the commands' help text and the
Markdown files), run in a folder holding small images under every name they use,
and must exit 0 with no traceback. A line that cannot run here is listed in
:data:`NOT_RUN` with the reason, and that list is checked too, so an example can
neither break nor drop out of the tests unnoticed. The few substitutions made
(:data:`SUBSTITUTE`) replace what only exists on a studio's network (a scheduler's
host name, ``/shots``) by its local equivalent.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from helpers.paths import ROOT
from pyramid_cli.cli import main

pytestmark = [pytest.mark.cli, pytest.mark.slow]


BIN = Path(sys.executable).parent
DOCUMENTS = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]

#: Lines of examples that no test runs, with why. Each must still be found in an example.
NOT_RUN = {
    "make demo": "the Makefile's own target: tests/test_goldens.py runs `make demo`'s job; a nested make here "
                 "would rebuild the environment under test",
    "make test": "this is the test suite itself",
    "deadline bundle submit ...": "AWS Deadline Cloud's client: a placeholder for the farm's own submission",
}

#: What exists only on a studio's network, replaced by its local equivalent (``{stage}`` is the example's folder).
SUBSTITUTE = {
    "tcp://scheduler:8786": "local:1",
    "/shots/": "{stage}/shots/",
}

#: Python blocks run after this prelude (names the README's snippets take as given).
PRELUDE = textwrap.dedent("""\
    import numpy as np
    import pyramid_cli as pyr
    from pyramid_cli.workflows import pyramids
    rng = np.random.default_rng(3)
    img = rng.random((48, 64, 4)).astype(np.float32)
    apple, orange = rng.random((48, 64, 3)).astype(np.float32), rng.random((48, 64, 3)).astype(np.float32)
    mask = np.zeros((48, 64, 1), np.float32); mask[:, :32] = 1
    arrays = [rng.random((24, 32, 3)).astype(np.float32) for _ in range(2)]
    u8 = (rng.random((48, 64, 3)) * 255).astype(np.uint8)
    """)

PROGRAMS = ("pyramid", "oiiotool", "idiff", "maketx", "openjd")


# --- the examples, as users read them -------------------------------------------------------------------------


def _join_continuations(lines: list[str]) -> list[str]:
    out: list[str] = []
    for line in lines:
        if out and out[-1].endswith("\\"):
            out[-1] = out[-1][:-1].rstrip() + " " + line.strip()
        else:
            out.append(line.strip())
    return [line for line in out if line]


def help_examples() -> dict[str, list[str]]:
    """``{command: [example lines]}`` from every command's ``--help``."""
    found = {}
    for name in sorted(main.commands):
        text = CliRunner().invoke(main, [name, "--help"], terminal_width=200).output
        m = re.search(r"^ *Examples?:\n((?: {2,}\S.*\n?)+)", text, re.M)
        found[name] = _join_continuations(m.group(1).splitlines()) if m else []
    return found


def markdown_blocks() -> list[tuple[str, str, str]]:
    """``(where, language, text)`` of every fenced block of the documents."""
    blocks = []
    for path in DOCUMENTS:
        lines = path.read_text(encoding="utf-8").splitlines()
        start = lang = None
        for i, line in enumerate(lines, 1):
            if line.startswith("```"):
                if start is None:
                    start, lang = i, line[3:].strip()
                else:
                    blocks.append((f"{path.relative_to(ROOT)}:{start}", lang, "\n".join(lines[start:i - 1])))
                    start = None
    return blocks


def _runs(line: str) -> bool:
    words = shlex.split(line, comments=True)
    return bool(words) and os.path.basename(words[0]) in PROGRAMS


# --- the folder the examples run in -------------------------------------------------------------------------


def _write(path: Path, pixels: np.ndarray, pixel_type: str | None = None) -> None:
    import pyramid_cli as pyr

    path.parent.mkdir(parents=True, exist_ok=True)
    if pixel_type is None:
        pyr.write_image(str(path), pixels)
    else:
        import OpenImageIO as oiio

        spec = oiio.ImageSpec(pixels.shape[1], pixels.shape[0], pixels.shape[2], pixel_type)
        out = oiio.ImageOutput.create(str(path))
        out.open(str(path), spec)
        out.write_image(np.ascontiguousarray(pixels, dtype=np.float32))
        out.close()


def _frames(folder: Path, name: str, first: int, last: int) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for f in range(first, last + 1):
        _write(folder / name.format(f), np.random.default_rng(f).random((8, 8, 3)).astype(np.float32))


def pyr_read(path: Path) -> np.ndarray:
    import pyramid_cli as pyr

    return pyr.read_image(str(path)).pixels


def build_stage(root: Path) -> None:
    """Small images under every name the examples use."""
    rng = np.random.default_rng(2007)
    h, w = 48, 64

    def rgb():
        return rng.random((h, w, 3)).astype(np.float32)

    def rgba_with_holes():
        px = rng.random((h, w, 4)).astype(np.float32)
        px[..., 3] = 1.0
        px[10:20, 12:30, 3] = 0.0
        px[30:34, 40:44, 3] = 0.5
        px[..., :3] *= px[..., 3:]
        return px

    def matte():
        m = np.zeros((h, w, 1), np.float32)
        m[:, : w // 2] = 1.0
        return m

    for name in ("render.exr", "in.exr", "tile.exr", "albedo.exr", "bump.exr", "plate.exr", "patch.exr",
                 "matte_32k.exr", "painting_32k.exr", "plate_16k.exr", "patch_16k.exr", "a.exr",
                 "out.exr",
                 "frames/a.exr", "frames/b.exr", "in/a.exr", "in/b.exr", "tex/albedo.1001.exr",
                 "tex/albedo.1002.exr", "plate_acescg.exr", "grade_acescct.exr", "grade.exr", "shot.exr",
                 "shot_log.exr"):
        _write(root / name, rgba_with_holes() if name in ("in.exr", "render.exr") else rgb())
    # tall enough that a fill of --levels 6 keeps 16 rows at its coarsest level, so it streams
    _write(root / "render_16k.exr", np.concatenate([rgba_with_holes()] * 22)[:1024])
    for name in ("small.png", "photo.png", "albedo.png", "apple.png", "orange.png", "tex/a.png", "tex/b.png",
                 "a.png", "map.png", "scan.tif", "slide.tif", "huge_32k.tif", "scans/a.tif", "scans/b.tif"):
        _write(root / name, rgb(), "uint8")
    for name in ("bake.png", "decal.png"):
        _write(root / name, rgba_with_holes(), "uint8")
    grey = rng.random((h, w, 1)).astype(np.float32)
    _write(root / "mask.png", np.repeat(grey, 3, axis=2), "uint8")
    for name in ("left_half.png", "left.png", "valid.png", "m.png"):
        _write(root / name, matte(), "uint8")
    _write(root / "matte.exr", matte())
    _write(root / "matte_16k.exr", matte())
    from helpers.colour import studio_config

    studio_config(root)  # studio.ocio: the colour examples' own config
    _write(root / "tex" / "flat.exr", np.full((h, w, 3), 0.25, np.float32))
    depth = rng.random((h, w, 1)).astype(np.float32)
    depth[5:9, 5:9] = np.nan
    _write(root / "depth.exr", depth)
    shutil.copy(root / "a.png", root / "b.png")
    a = pyr_read(root / "a.exr")
    _write(root / "b.exr", a + np.float32(1e-6))  # a near-copy: `pyramid diff a.exr b.exr` passes
    shutil.copy(root / "out.exr", root / "golden.exr")
    shutil.copy(root / "out.exr", root / "gpu.exr")
    shutil.copy(root / "out.exr", root / "reference.exr")
    base = rgb()
    _write(root / "float.exr", base, "float")
    _write(root / "half.exr", base, "half")
    for folder in ("out", "golden"):
        _write(root / folder / "a.exr", base)
        _write(root / folder / "sub" / "b.exr", base[::2, ::2])
    _frames(root, "plate.{:04d}.exr", 1001, 1240)
    for shot in (root / "shots" / "sh010", root / "shots" / "sh010" / "plate"):
        for f in range(1001, 1241):
            shot.mkdir(parents=True, exist_ok=True)
            os.link(root / f"plate.{f:04d}.exr", shot / f"plate.{f:04d}.exr")
    runner = CliRunner()
    for args in (["mipmap", "--backend", "cpu", "albedo.exr", "out.tx"],
                 ["levels", "--backend", "cpu", "--laplacian", "--multipart", "render.exr", "bands.exr"],
                 ["levels", "--backend", "cpu", "--laplacian", "render.exr", "pyr/band_{level}.exr"]):
        cwd = os.getcwd()
        os.chdir(root)
        try:
            r = runner.invoke(main, args)
        finally:
            os.chdir(cwd)
        assert r.exit_code == 0, r.output
    shutil.copy(root / "out.tx", root / "golden.tx")


@pytest.fixture(scope="module")
def template_stage(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("examples") / "stage"
    root.mkdir()
    build_stage(root)
    return root


@pytest.fixture
def stage(template_stage, tmp_path) -> Path:
    """A copy of the stage for one block, whose lines run in order as pasted into a shell (hard links: the
    stage's files are never written, only replaced)."""
    root = tmp_path / "stage"
    shutil.copytree(template_stage, root, copy_function=os.link)
    return root


def _environment(stage: Path, **extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("SLURM_", "SGE_", "LSB_", "PBS_", "AWS_BATCH",
                                                                        "JOB_COMPLETION", "PYRAMID_SHARD"))}
    env["PATH"] = f"{BIN}{os.pathsep}{env.get('PATH', '')}"
    # `--shard auto` in an example runs as the one task of a one-task Slurm array
    env.update({"SLURM_ARRAY_TASK_ID": "1", "SLURM_ARRAY_TASK_MIN": "1", "SLURM_ARRAY_TASK_MAX": "1",
                "SLURM_ARRAY_TASK_STEP": "1", "SLURM_ARRAY_TASK_COUNT": "1"})
    env.update(extra)
    return env


def _localise(text: str, stage: Path) -> str:
    for old, new in SUBSTITUTE.items():
        text = text.replace(old, new.format(stage=stage))
    return text.replace(".venv/bin/", "")


def run_shell(line: str, stage: Path, env: dict[str, str] | None = None, timeout: int = 300):
    r = subprocess.run(["bash", "-c", _localise(line, stage)], cwd=stage, env=env or _environment(stage),
                       capture_output=True, text=True, timeout=timeout)
    assert r.returncode == 0 and "Traceback" not in r.stderr, (
        f"{line}\nexit {r.returncode}\n--- stdout\n{r.stdout[-3000:]}\n--- stderr\n{r.stderr[-3000:]}")
    return r


# --- the tests ---------------------------------------------------------------------------------------------


HELP = help_examples()


def test_every_command_has_examples():
    assert [name for name, lines in HELP.items() if not lines] == []


@pytest.mark.parametrize("command", sorted(HELP))
def test_help_examples_run(command, stage):
    for line in HELP[command]:
        if line.split(" #")[0].strip() in NOT_RUN:
            continue
        assert _runs(line), f"`pyramid {command} --help` shows an example no test runs: {line}"
        run_shell(line, stage)


BLOCKS = markdown_blocks()


def _shell_lines(text: str) -> list[str]:
    return [line for line in _join_continuations(text.splitlines()) if not line.startswith("#")]


def _block_id(block) -> str:
    return block[0]


@pytest.mark.parametrize("block", [b for b in BLOCKS if b[1] in ("sh", "bash")], ids=_block_id)
def test_shell_blocks_run(block, stage):
    where, _, text = block
    if text.startswith("#!"):
        _run_array_script(text, stage)
        return
    for line in _shell_lines(text):
        if line.split(" #")[0].strip() in NOT_RUN:
            continue
        assert _runs(line), f"{where}: an example no test runs: {line}"
        run_shell(line, stage)


def _run_array_script(text: str, stage: Path) -> None:
    """A batch script with ``#SBATCH --array=A-B``: run it once per array task, as Slurm would."""
    m = re.search(r"^#SBATCH .*--array=(\d+)-(\d+)(?::(\d+))?", text, re.M)
    assert m, "a script example must be a Slurm array script"
    first, last, step = int(m.group(1)), int(m.group(2)), int(m.group(3) or 1)
    script = stage / "job.sh"
    script.write_text(_localise(text, stage))
    tasks = list(range(first, last + 1, step))
    for task in tasks:
        env = _environment(stage, SLURM_ARRAY_TASK_ID=str(task), SLURM_ARRAY_TASK_MIN=str(first),
                           SLURM_ARRAY_TASK_MAX=str(last), SLURM_ARRAY_TASK_STEP=str(step),
                           SLURM_ARRAY_TASK_COUNT=str(len(tasks)))
        run_shell(f"bash {shlex.quote(str(script))}", stage, env)
    outputs = re.findall(r"-o (\S+)", text)
    assert outputs, "the script's outputs are named with -o"
    _assert_every_frame(_localise(outputs[0], stage))


def _assert_every_frame(pattern: str) -> None:
    from pyramid_cli.run.sequence import parse

    seq = parse(pattern)
    folder = Path(seq.frame(0)).parent
    assert sorted(p.name for p in folder.iterdir() if not p.name.startswith(".")) == \
        [Path(seq.frame(f)).name for f in range(1001, 1241)]


@pytest.mark.parametrize("block", [b for b in BLOCKS if b[1] == "yaml" and "completionMode: Indexed" in b[2]],
                         ids=_block_id)
def test_kubernetes_indexed_job_runs_every_frame(block, stage):
    """The Kubernetes Indexed Job's container command, once per completion index, as Kubernetes runs it."""
    import yaml

    job = yaml.safe_load(block[2])
    (container,) = job["spec"]["template"]["spec"]["containers"]
    command = [str(a) for a in container["command"]]
    for index in range(job["spec"]["completions"]):
        env = _environment(stage, JOB_COMPLETION_INDEX=str(index))
        for k in [k for k in env if k.startswith("SLURM_")]:
            del env[k]
        run_shell(shlex.join(command), stage, env)
    _assert_every_frame(_localise(command[command.index("-o") + 1], stage))


@pytest.mark.parametrize("block", [b for b in BLOCKS if b[1] == "make"], ids=_block_id)
def test_makefile_blocks_run(block, stage):
    """A Makefile snippet: its targets in the order a user meets them (check, accept, check again)."""
    (stage / "samples").mkdir()
    for name in ("apple.png", "orange.png"):
        shutil.copy(stage / name, stage / "samples" / name)
    (stage / "Makefile").write_text(block[2] + "\n")
    targets = re.findall(r"^([\w-]+):", block[2], re.M)
    assert targets == ["golden-check", "golden-update"], targets
    first = subprocess.run(["make", "golden-check"], cwd=stage, env=_environment(stage), capture_output=True,
                           text=True, timeout=300)
    assert first.returncode != 0 and "Traceback" not in first.stderr  # no goldens yet: the check fails
    run_shell("make golden-update && make golden-check", stage)
    assert (stage / "out" / "junit.xml").exists() and (stage / "out" / "diff-report").is_dir()


@pytest.mark.parametrize("block", [b for b in BLOCKS if b[1] == "python"], ids=_block_id)
def test_python_blocks_run(block, stage):
    code = PRELUDE + block[2]
    r = subprocess.run([sys.executable, "-c", code], cwd=stage, env=_environment(stage), capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, f"{block[0]}\n{r.stderr[-3000:]}"


def test_not_run_lines_still_exist():
    text = "\n".join(line for lines in HELP.values() for line in lines)
    text += "\n".join(b[2] for b in BLOCKS)
    assert [line for line in NOT_RUN if line not in text] == []


def test_every_block_is_run_or_named():
    """A fenced block in a language no test above runs is listed here with why."""
    not_examples = {"yaml": "CI configuration (GitHub Actions, GitLab) and the Kubernetes Job, run above",
                    "": "a terminal session shown with its output", "python": "run above", "make": "run above",
                    "text": "an install recipe with a placeholder for the clone's address",
                    **{d: "a MyST directive of the docs site (its structure, not an example)"
                       for d in ("{toctree}", "{image}", "{eval-rst}")}}
    assert [b[0] for b in BLOCKS if b[1].split(" ")[0] not in ("sh", "bash", *not_examples)] == []


def test_the_stage_reads_as_the_examples_expect(template_stage):
    import pyramid_cli as pyr

    assert np.isnan(pyr.read_image(str(template_stage / "depth.exr")).pixels).any()
    bake = pyr.read_image(str(template_stage / "bake.png")).pixels
    assert bake.shape[2] == 4 and (bake[..., 3] < 1).any()  # fill and mipmap --fill have holes to fill
