"""Reads the cohort manifest into jobs: one `posereg register` per target, or one
`posereg series` per subject (mode = series)."""

import csv
import shlex
from dataclasses import dataclass, field

REQUIRED = ("subject", "source", "source_labels", "targets")
# Bytes a registration holds per target voxel at its peak (posereg's own estimate, with
# room for the Python wrapper); the base covers the program itself.
BYTES_PER_VOXEL = 400
BASE_MB = 300


@dataclass
class Job:
    """One posereg run: its input files and its arguments."""

    verb: str
    source: str
    source_labels: str
    targets: list
    settings: str = ""
    inputs: dict = field(init=False)

    def __post_init__(self):
        self.inputs = {"source": self.source, "source_labels": self.source_labels}
        self.inputs.update({f"target_{k}": t for k, t in enumerate(self.targets)})
        if self.settings:
            self.inputs["settings"] = self.settings

    def command(self, posereg, out):
        """The command line, as one shell-quoted string."""
        args = [posereg, self.verb, "--source", self.source, "--source-labels", self.source_labels]
        if self.verb == "series":
            args += ["--targets", *self.targets]
        else:
            args += ["--target", self.targets[0]]
        args += ["-o", out]
        if self.settings:
            args += ["--config", self.settings]
        return " ".join(quote(a) for a in args)


def quote(arg):
    return shlex.quote(str(arg))


def read_manifest(path):
    """Job name ("<subject>/pose_NN" or "<subject>/series") → Job, in manifest order. Refuses
    a manifest that lacks a column, repeats a subject or names a subject that is not a plain
    folder name."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        raise ValueError(f"{path}: the manifest has no rows")
    missing = [c for c in REQUIRED if c not in rows[0]]
    if missing:
        raise ValueError(f"{path}: missing column(s) {', '.join(missing)}; need {', '.join(REQUIRED)}")
    jobs, seen = {}, set()
    for line, row in enumerate(rows, start=2):
        subject = (row["subject"] or "").strip()
        if not subject or "/" in subject or subject.startswith(".") or subject == "cohort":
            raise ValueError(f"{path}:{line}: subject {subject!r} is not a usable folder name")
        if subject in seen:
            raise ValueError(f"{path}:{line}: subject {subject} is listed twice")
        seen.add(subject)
        targets = [t.strip() for t in (row["targets"] or "").split(";") if t.strip()]
        if not targets:
            raise ValueError(f"{path}:{line}: subject {subject} has no targets")
        mode = (row.get("mode") or "register").strip()
        settings = (row.get("settings") or "").strip()
        common = dict(source=row["source"].strip(), source_labels=row["source_labels"].strip(),
                      settings=settings)
        if mode == "series":
            jobs[f"{subject}/series"] = Job("series", targets=targets, **common)
        elif mode == "register":
            for k, target in enumerate(targets, start=1):
                jobs[f"{subject}/pose_{k:02d}"] = Job("register", targets=[target], **common)
        else:
            raise ValueError(f"{path}:{line}: mode {mode!r} is neither register nor series")
    return jobs


def memory_mb(inputs):
    """Memory to declare for a job: from the largest target's voxel count (read from its
    header); a file that cannot be read gets the base (its registration will say what is
    wrong with it)."""
    import nibabel

    voxels = 0
    for name, path in inputs.items():
        if name.startswith("target_"):
            try:
                x, y, z = (nibabel.load(path).shape + (1, 1))[:3]
                voxels = max(voxels, x * y * z)
            except Exception:
                pass
    return BASE_MB + voxels * BYTES_PER_VOXEL // 1_000_000
