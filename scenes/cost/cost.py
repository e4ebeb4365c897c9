"""The glint-map cost comparison of docs/performance.md ("Glint maps").

Renders scenes/glitter_pattern.toml and its variants in this folder (uniform, a constant map of
ones, the density map alone), each with glints and with --smooth, alternating, ROUNDS times,
on one thread, and prints a Markdown table of medians: the render's wall time (the JSON's
`seconds`), the process's CPU time (user + system, steadier than wall time on a shared
machine; it includes loading the scene, the same for the glint and smooth runs), the glint
queries traversed, nodes per query, and each material's times against the uniform material's.

Usage, from the repository root after `cargo build --release -p xtask --no-default-features`:

    python3 scenes/cost/cost.py [ROUNDS] [--resolution WxH] [--spp N]
"""

import argparse
import json
import resource
import statistics
import subprocess
from pathlib import Path

VARIANTS = [
    ("uniform", "scenes/cost/glitter_pattern_uniform.toml"),
    ("ones", "scenes/cost/glitter_pattern_ones.toml"),
    ("density", "scenes/cost/glitter_pattern_density.toml"),
    ("all three maps", "scenes/glitter_pattern.toml"),
]


def cpu_seconds():
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def render(scene, smooth, args, out):
    command = ["target/release/xtask", "render", scene, "--threads", "1", "--quiet",
               "--resolution", args.resolution, "--spp", str(args.spp), "--out", str(out)]
    if smooth:
        command.append("--smooth")
    before = cpu_seconds()
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
    cpu = cpu_seconds() - before
    stem = Path(scene).stem + ("_smooth" if smooth else "")
    report = json.loads((out / f"{stem}.json").read_text())
    return report, cpu


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("rounds", nargs="?", type=int, default=5)
    parser.add_argument("--resolution", default="320x180")
    parser.add_argument("--spp", type=int, default=8)
    parser.add_argument("--out", default="target/map-cost")
    args = parser.parse_args()
    out = Path(args.out)
    runs = {(name, smooth): [] for name, _ in VARIANTS for smooth in (False, True)}
    for _ in range(args.rounds):
        for name, scene in VARIANTS:
            for smooth in (False, True):
                runs[(name, smooth)].append(render(scene, smooth, args, out))
    median = statistics.median
    uniform = runs[("uniform", False)]
    print(f"{args.rounds} alternating rounds, {args.resolution}, {args.spp} spp, one thread")
    print()
    print("| material | glint wall s | smooth wall s | glint CPU s | smooth CPU s "
          "| traversed queries | nodes per query | glint wall / uniform's "
          "| glint CPU / uniform's |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, _ in VARIANTS:
        glint, smooth = runs[(name, False)], runs[(name, True)]
        report = glint[0][0]
        traversed = report["glint_queries"] - report["negligible_queries"]
        wall = median(g[0]["seconds"] / u[0]["seconds"] for g, u in zip(glint, uniform))
        cpu = median(g[1] / u[1] for g, u in zip(glint, uniform))
        print(f"| {name} | {median(g[0]['seconds'] for g in glint):.2f} "
              f"| {median(s[0]['seconds'] for s in smooth):.2f} "
              f"| {median(g[1] for g in glint):.2f} | {median(s[1] for s in smooth):.2f} "
              f"| {traversed} | {report['nodes_per_query']:.1f} "
              f"| {wall:.2f}× | {cpu:.2f}× |")


if __name__ == "__main__":
    main()
