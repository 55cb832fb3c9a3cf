"""Regenerate the numbers quoted in docs/fly.md ("From a result to a model you can fly").

Runs the page's example end to end in a temporary folder, through the command line and the
Python API a user types: ``flightid run`` of the CSV walk-through case, a prediction on a
second maneuver (a doublet simulated from the same true short-period model, with its own
noise), the linear model and its modes, and ``flightid export`` in every format; then
prints each block the page quotes, under the key of its ``<!-- fly: KEY -->`` marker.

    python docs/fly_numbers.py            # print the blocks
    python docs/fly_numbers.py --check    # compare them with docs/fly.md

``--check`` compares every number of a quoted block with the fresh one to the digits the
page prints (one unit of the last printed digit); words must agree exactly.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
WALK = ROOT / "examples" / "csv_walkthrough"
DOC = ROOT / "docs" / "fly.md"
# the true short-period model of examples/csv_walkthrough/make_flight.py
TRUE = {"Za": -0.8, "Zq": 0.05, "Zde": -0.1, "Ma": -4.5, "Mq": -1.6, "Mde": -7.0}
# measurement noise of the simulated maneuvers: α in deg, q in deg/s (make_flight.py)
NOISE_DEG = {"alpha": 0.02, "q": 0.05}
_MARKER = re.compile(r"<!--\s*fly:\s*([\w-]+)\s*-->")
_NUMBER = re.compile(r"^[−+-]?(\d+\.?\d*|\.\d+)(e[−+-]?\d+)?$", re.IGNORECASE)


def _cli(*argv: str) -> str:
    """``flightid ARGV`` in this process; its standard output (a failure raises)."""
    from flightid.cli.main import main

    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        code = main(list(argv))
    if code != 0:
        raise RuntimeError(f"flightid {' '.join(argv)} exited with {code}")
    return out.getvalue()


def doublet(seed: int = 7):
    """A 2° elevator doublet (1 s each way from t = 1 s), 8 s at 50 Hz, flown by the true
    model with the input held over each sample (exact discretization) and the noise of
    make_flight.py: a ``FlightData`` in rad and rad/s."""
    from scipy.linalg import expm

    from flightid.data.flightdata import FlightData

    rng = np.random.default_rng(seed)
    dt, n = 0.02, 401
    t = np.arange(n) * dt
    de = np.zeros(n)
    de[(t >= 1.0) & (t < 2.0)] = np.deg2rad(2.0)
    de[(t >= 2.0) & (t < 3.0)] = -np.deg2rad(2.0)
    za, zq, zde, ma, mq, mde = TRUE.values()
    augmented = np.zeros((3, 3))
    augmented[:2, :2] = [[za, 1.0 + zq], [ma, mq]]
    augmented[:2, 2] = [zde, mde]
    # expm([[A, B], [0, 0]] Δt) = [[Φ, Γ], [0, 1]]
    exponential = expm(augmented * dt)
    phi, gamma = exponential[:2, :2], exponential[:2, 2]
    x = np.zeros((n, 2))
    for k in range(n - 1):
        # x_{k+1} = Φ x_k + Γ δe_k
        x[k + 1] = phi @ x[k] + gamma * de[k]
    alpha = x[:, 0] + np.deg2rad(rng.normal(0, NOISE_DEG["alpha"], n))
    q = x[:, 1] + np.deg2rad(rng.normal(0, NOISE_DEG["q"], n))
    return FlightData(
        t,
        {"de": de},
        {"alpha": alpha, "q": q},
        units={"de": "rad", "alpha": "rad", "q": "rad/s"},
        name="doublet",
    )


def _true_mode() -> tuple[float, float]:
    """ω_n (rad/s) and ζ of the true short period (eigenvalues of the true A)."""
    za, zq, _, ma, mq, _ = TRUE.values()
    eigenvalue = np.linalg.eigvals(np.array([[za, 1.0 + zq], [ma, mq]]))[0]
    omega = abs(eigenvalue)
    return float(omega), float(-eigenvalue.real / omega)


def _standalone_difference(folder: Path, module: Path, maneuver, expected) -> float:
    """Max |y_module − y_flightid| of the exported module run without flightid."""
    runner = folder / "runner.py"
    runner.write_text(
        "import importlib, sys\nimport numpy as np\nsys.path.insert(0, sys.argv[1])\n"
        "m = importlib.import_module(sys.argv[2])\nd = np.load(sys.argv[3])\n"
        "np.save(sys.argv[4], m.simulate(d['t'], d['u']))\n",
        encoding="utf-8",
    )
    np.savez(folder / "in.npz", t=maneuver.time, u=maneuver.channel("de").reshape(-1, 1))
    subprocess.run(
        [sys.executable, "-I", str(runner), str(module.parent), module.stem,
         str(folder / "in.npz"), str(folder / "out.npy")],
        check=True,
        timeout=120,
    )  # fmt: skip
    return float(np.max(np.abs(np.load(folder / "out.npy") - expected)))


def run_example(folder: Path) -> dict[str, str]:
    """The page's example in ``folder``; the quoted blocks by key."""
    from flightid.cases import load_run

    shutil.copytree(WALK, folder / "csv_walkthrough", dirs_exist_ok=True)
    case = folder / "csv_walkthrough" / "my_case.toml"
    out = folder / "my_flight"
    _cli("run", str(case), "--out", str(out), "--quiet", "--accuracy", "none")
    run = load_run(out)
    blocks: dict[str, str] = {}

    new = doublet()
    prediction = run.predict(new)
    rows = ["| output | RMS error | noise σ | R² |", "|---|---|---|---|"]
    for name, rms, r2 in zip(prediction.output_names, prediction.rms, prediction.r2, strict=True):
        unit = "rad/s" if name == "q" else "rad"
        noise = math.radians(NOISE_DEG[name])
        rows.append(f"| {name} ({unit}) | {rms:.3e} | {noise:.3e} | {r2:.4f} |")
    blocks["prediction"] = "\n".join(rows)

    linear = run.linearize()
    blocks["linear"] = linear.summary()

    (mode,) = linear.modes()
    omega_true, zeta_true = _true_mode()
    blocks["modes"] = "\n".join(
        [
            "| | estimate | σ | true value |",
            "|---|---|---|---|",
            f"| ω_n (rad/s) | {mode.natural_frequency:.4f} | {mode.natural_frequency_std:.4f} "
            f"| {omega_true:.4f} |",
            f"| ζ | {mode.damping_ratio:.4f} | {mode.damping_ratio_std:.4f} | {zeta_true:.4f} |",
        ]
    )

    written = []
    for fmt, name in (("statespace", "short_period"), ("mat", "short_period"),
                      ("python", "short_period_model")):  # fmt: skip
        printed = _cli("export", str(out), "--format", fmt, "--out", str(folder / name))
        written += [Path(line.split(": ", 1)[1]).name for line in printed.splitlines()]
    blocks["files"] = " ".join(written)
    maneuver = run.maneuvers[0]
    expected = run.simulate(maneuver)
    difference = _standalone_difference(
        folder, folder / "short_period_model.py", maneuver, expected
    )
    blocks["standalone"] = (
        f"largest difference {'below 1e-12' if difference < 1e-12 else f'{difference:.1e}'} "
        f"(outputs up to {np.max(np.abs(expected)):.4f})"
    )
    return blocks


def quoted_blocks(text: str) -> dict[str, str]:
    """The block after each ``<!-- fly: KEY -->`` marker: the fenced code or the table."""
    blocks = {}
    for match in _MARKER.finditer(text):
        rest = text[match.end() :].lstrip("\n")
        if rest.startswith("```"):
            body = rest.split("\n", 1)[1]
            blocks[match.group(1)] = body.split("\n```", 1)[0]
        else:
            lines = []
            for line in rest.splitlines():
                if not line.strip():
                    break
                lines.append(line)
            blocks[match.group(1)] = "\n".join(lines)
    return blocks


def _tokens(text: str) -> list[str]:
    return [t for t in re.split(r"[\s|(),:±\[\]]+", text) if t]


def _agree(page: str, fresh: str) -> bool:
    if _NUMBER.match(page) and _NUMBER.match(fresh):
        a, b = (float(s.replace("−", "-")) for s in (page, fresh))
        mantissa = page.lower().split("e")[0]
        digits = len(mantissa.split(".")[1]) if "." in mantissa else 0
        exponent = int(page.lower().split("e")[1]) if "e" in page.lower() else 0
        # one unit of the page's last printed digit
        return abs(a - b) <= 1.0001 * 10.0 ** (exponent - digits)
    return page == fresh


def compare(text: str, fresh: dict[str, str]) -> list[str]:
    """What differs between the page's quoted blocks and ``fresh``, one line each."""
    problems = []
    quoted = quoted_blocks(text)
    for key in fresh:
        if key not in quoted:
            problems.append(f"{key}: not quoted on the page")
    for key, block in quoted.items():
        if key not in fresh:
            problems.append(f"{key}: not produced by this script")
            continue
        page, new = _tokens(block), _tokens(fresh[key])
        if len(page) != len(new):
            problems.append(f"{key}: {len(page)} tokens on the page, {len(new)} now")
            continue
        for a, b in zip(page, new, strict=True):
            if not _agree(a, b):
                problems.append(f"{key}: page {a!r}, now {b!r}")
    return problems


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true", help="compare with docs/fly.md")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        blocks = run_example(Path(tmp))
    if args.check:
        problems = compare(DOC.read_text(encoding="utf-8"), blocks)
        print("\n".join(problems) or "docs/fly.md agrees with this run")
        return 1 if problems else 0
    for key, block in blocks.items():
        print(f"<!-- fly: {key} -->\n{block}\n")
    return 0


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT / "src"))
    sys.exit(main())
