"""The cohort workflow (workflow/Snakefile) run as a lab would: three small phantom pairs (one
as a two-pose series) and one pair whose target is corrupt, from a manifest, with the local
profile; then again (nothing to do), after deleting one pair (only that pair redone, to the
same bytes), and a dry run with the Slurm profile (every job listed with its resources).

    POSEREG=target/release/posereg SNAKEMAKE=.venv-workflow/bin/snakemake python3 tests/workflow.py

With --slurm (scripts/slurm-cohort starts a single-node Slurm first) the same cohort then runs
again through that Slurm with the Slurm profile: every field the same bytes as the local run's;
and one pair as a GPU job (one GPU asked of Slurm, the job on whatever Vulkan adapter the node
has).
"""

import csv
import json
import os
import shutil
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
POSEREG = os.environ["POSEREG"]
SNAKEMAKE = os.environ["SNAKEMAKE"]


def run(args, **kw):
    done = subprocess.run(args, capture_output=True, text=True, **kw)
    assert done.returncode == 0, f"{args} failed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return done.stdout + done.stderr


def phantom(out, flexion, seed):
    run([POSEREG, "phantom", "--size", "quarter", "--flexion", str(flexion), "--seed", str(seed),
         "-q", "-o", out])
    return os.path.join(out, "image.nii.gz")


def snakemake(d, profile, *extra, results="results", manifest="manifest.csv", config=()):
    return run([SNAKEMAKE, "-s", os.path.join(ROOT, "workflow", "Snakefile"),
                "--profile", os.path.join(ROOT, "workflow", "profiles", profile),
                "--cores", "2", "--config", f"manifest={d}/{manifest}",
                f"posereg={POSEREG}", f"results={d}/{results}", *config, *extra], cwd=d)


# The Slurm executor plugin's settings for a cluster without accounting: job states from squeue
# (the cluster keeps finished jobs for a day, MinJobAge), no account, the one partition.
SLURM = ["--slurm-status-command", "squeue", "--slurm-no-account",
         "--default-resources", "slurm_partition=main", "runtime=30", "mem_mb=2000",
         "--latency-wait", "5"]


def fields(results):
    """Every field.nii.gz under `results`, by its path there, with its bytes."""
    found = {}
    for folder, _, files in os.walk(results):
        for name in files:
            if name == "field.nii.gz":
                with open(os.path.join(folder, name), "rb") as f:
                    found[os.path.relpath(os.path.join(folder, name), results)] = f.read()
    return found


def through_slurm(d, source, labels, fast):
    """The cohort again through Slurm: the same field bytes as the local run; then one pair as
    a GPU job."""
    try:
        snakemake(d, "slurm", *SLURM, results="slurm")
    except AssertionError:
        for folder, _, files in os.walk(f"{d}/.snakemake/slurm_logs"):
            for name in files:
                with open(os.path.join(folder, name)) as f:
                    print(f"--- {name}\n{f.read()[-3000:]}", file=sys.stderr)
        raise
    local, slurm = fields(f"{d}/results"), fields(f"{d}/slurm")
    assert sorted(local) == sorted(slurm) and len(local) == 4, (sorted(local), sorted(slurm))
    differ = [k for k in local if local[k] != slurm[k]]
    assert not differ, f"fields differ between the local and the Slurm run: {differ}"
    with open(f"{d}/gpu.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["subject", "source", "source_labels", "targets", "settings", "mode"])
        w.writerow(["g", source, labels, f"{d}/a/image.nii.gz", fast, "register"])
    listed = snakemake(d, "slurm", *SLURM, "--verbose", results="gpu", manifest="gpu.csv",
                       config=["device=gpu"])
    assert "--gpus=1" in listed, listed[-3000:]
    with open(f"{d}/gpu/g/pose_01/report.json") as f:
        device = json.load(f)["device"]
    assert device.startswith("gpu"), device
    print(f"slurm: 4 fields as the local run's; the GPU job ran on {device}")


def stamps(d):
    results = os.path.join(d, "results")
    return {os.path.relpath(os.path.join(r, f), results): os.stat(os.path.join(r, f)).st_mtime_ns
            for r, _, files in os.walk(results) for f in files if f == "status.json"}


def main():
    d = tempfile.mkdtemp()
    try:
        source = phantom(f"{d}/s", 0, 1)
        labels = f"{d}/s/labels.nii.gz"
        a, b = phantom(f"{d}/a", 30, 2), phantom(f"{d}/b", 45, 3)
        c1, c2 = phantom(f"{d}/c1", 30, 4), phantom(f"{d}/c2", 60, 5)
        with open(a, "rb") as f:
            head = f.read(3000)
        corrupt = f"{d}/corrupt.nii.gz"
        with open(corrupt, "wb") as f:
            f.write(head)
        fast = f"{d}/fast.toml"
        with open(fast, "w") as f:
            f.write('[adaptive]\niterations = "3x3x3"\n')
        rows = [("a", a, "register"), ("b", b, ""), ("c", f"{c1};{c2}", "series"),
                ("d", corrupt, "register")]
        with open(f"{d}/manifest.csv", "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["subject", "source", "source_labels", "targets", "settings", "mode"])
            for subject, targets, mode in rows:
                w.writerow([subject, source, labels, targets, fast, mode])

        snakemake(d, "local")
        results = f"{d}/results"
        for job in ("a/pose_01", "b/pose_01", "c/series/pose_01", "c/series/pose_02"):
            for name in ("field.nii.gz", "report.json", "kinematics.csv"):
                assert os.path.exists(f"{results}/{job}/{name}"), f"no {job}/{name}"
        with open(f"{results}/cohort/summary.csv", newline="") as f:
            summary = list(csv.DictReader(f))
        assert [r["job"] for r in summary] == ["a/pose_01", "b/pose_01", "c/series/pose_01",
                                                "c/series/pose_02"], summary
        for r in summary:
            assert float(r["correlation_after"]) > float(r["correlation_before"]), r
            assert abs(float(r["tibiofemoral_flexion"])) > 20, r
        with open(f"{results}/cohort/failed.csv", newline="") as f:
            failed = list(csv.DictReader(f))
        assert [r["job"] for r in failed] == ["d/pose_01"], failed
        assert "corrupt.nii.gz" in failed[0]["error"], failed
        assert os.path.getsize(f"{results}/cohort/summary.png") > 1000

        before = stamps(d)
        again = snakemake(d, "local")
        assert "Nothing to be done" in again, again[-2000:]
        assert stamps(d) == before

        with open(f"{results}/b/pose_01/field.nii.gz", "rb") as f:
            field = f.read()
        shutil.rmtree(f"{results}/b")
        snakemake(d, "local")
        after = stamps(d)
        redone = sorted(k for k in after if after[k] != before.get(k))
        assert redone == ["b/pose_01/status.json"], redone
        with open(f"{results}/b/pose_01/field.nii.gz", "rb") as f:
            assert f.read() == field, "the pair redone gave other field bytes"

        listed = snakemake(d, "slurm", "--dry-run", "--forceall")
        for job in ("subject=a, name=pose_01", "subject=c, name=series", "subject=d, name=pose_01"):
            assert job in listed, f"{job} not listed:\n{listed[-3000:]}"
        assert "mem_mb=" in listed and "slurm_partition=" in listed, listed[-3000:]
        if "--slurm" in sys.argv:
            through_slurm(d, source, labels, fast)
        print("workflow: ok")
    finally:
        shutil.rmtree(d, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
