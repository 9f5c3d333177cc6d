"""The cohort's summary: one row per registered pose (the figures of its report.json, its bones
and its kinematics), the failed jobs listed apart, and a figure.

    summarise.py --table summary.csv --failed failed.csv --figure summary.png RESULTS/*/*/status.json
"""

import argparse
import csv
import json
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

KINEMATICS = ("tibiofemoral", "patellofemoral")


def load(path):
    with open(path) as f:
        return json.load(f)


def kinematics(folder):
    """joint_quantity → change, from kinematics.csv (empty when it was not written)."""
    path = os.path.join(folder, "kinematics.csv")
    if not os.path.exists(path):
        return {}
    with open(path, newline="") as f:
        return {f"{r['joint']}_{r['quantity']}": float(r["change"]) for r in csv.DictReader(f)}


def pose_row(job, folder):
    """One registered pose's row from the files register writes."""
    report = load(os.path.join(folder, "report.json"))
    row = {
        "job": job,
        "target": report["inputs"].get("target", ""),
        "status": "ok",
        "seconds": round(report["seconds"], 1),
        "correlation_before": round(report["correlation"]["before"], 4),
        "correlation_after": round(report["correlation"]["after"], 4),
        "control_points": report["control_points"],
        "jacobian_min": round(report["jacobian"]["min"], 4),
        "folded_share": report["jacobian"]["folded_share"],
        "checks_failed": ";".join(c["name"] for c in report["checks"] if not c["passed"]),
    }
    for bone in (report.get("initialisation") or {}).get("bones", []):
        row[f"{bone['name']}_decision"] = bone["confidence"]["decision"]
        row[f"{bone['name']}_warnings"] = len(bone["confidence"]["warnings"])
    row.update({k: round(v, 3) for k, v in kinematics(folder).items()})
    return row


def job_rows(status_path):
    """The rows of one job: its poses when it succeeded, one failed row otherwise."""
    folder = os.path.dirname(status_path)
    job = os.path.relpath(folder, os.path.dirname(os.path.dirname(folder)))
    status = load(status_path)
    if status["status"] != "ok":
        return [{"job": job, "status": "failed", "error": status["error"].replace("\n", " | ")}]
    if os.path.exists(os.path.join(folder, "series.json")):
        poses = sorted(d for d in os.listdir(folder) if d.startswith("pose_"))
        return [pose_row(f"{job}/{p}", os.path.join(folder, p)) for p in poses]
    return [pose_row(job, folder)]


def write_csv(path, rows, first):
    columns = list(first) + sorted({k for r in rows for k in r} - set(first))
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, columns)
        w.writeheader()
        w.writerows(rows)


def figure(path, rows):
    """Correlation before and after, and the tibiofemoral flexion change, per pose."""
    ok = [r for r in rows if r["status"] == "ok"]
    names = [r["job"] for r in ok]
    fig, (a, b) = plt.subplots(2, 1, figsize=(max(6, 0.6 * len(names) + 2), 7))
    x = range(len(names))
    a.bar([i - 0.2 for i in x], [r["correlation_before"] for r in ok], 0.4, label="before")
    a.bar([i + 0.2 for i in x], [r["correlation_after"] for r in ok], 0.4, label="after")
    a.set_ylabel("correlation with the target")
    a.legend(loc="lower right")
    flexion = [r.get("tibiofemoral_flexion", float("nan")) for r in ok]
    b.bar(list(x), flexion)
    b.set_ylabel("tibiofemoral flexion change (deg)")
    for axis in (a, b):
        axis.set_xticks(list(x))
        axis.set_xticklabels(names, rotation=45, ha="right", fontsize=8)
    failed = [r["job"] for r in rows if r["status"] != "ok"]
    title = f"{len(ok)} poses registered"
    title += f"; failed: {', '.join(failed)}" if failed else ""
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--table", required=True)
    p.add_argument("--failed", required=True)
    p.add_argument("--figure", required=True)
    p.add_argument("status", nargs="+")
    a = p.parse_args()
    rows = [r for s in sorted(a.status) for r in job_rows(s)]
    first = ("job", "target", "status", "seconds", "correlation_before", "correlation_after",
             "control_points", "jacobian_min", "folded_share", "checks_failed")
    write_csv(a.table, [r for r in rows if r["status"] == "ok"], first)
    write_csv(a.failed, [r for r in rows if r["status"] != "ok"], ("job", "status", "error"))
    figure(a.figure, rows)
    failed = sum(r["status"] != "ok" for r in rows)
    if failed:
        print(f"summary: {failed} job(s) failed; see {a.failed}")


main()
