"""Runs one posereg job and records how it went in status.json, so that one pair's failure
(a corrupt scan, labels without bones) does not stop the cohort: the summary lists it.

    run_pair.py --status OUT/status.json --threads N --device D -- posereg register ...
"""

import argparse
import json
import os
import subprocess
import time

p = argparse.ArgumentParser()
p.add_argument("--status", required=True)
p.add_argument("--threads", type=int, required=True)
p.add_argument("--device", required=True)
p.add_argument("command", nargs=argparse.REMAINDER)
a = p.parse_args()
command = [c for c in a.command if c != "--"]
command += ["--threads", str(a.threads), "--device", a.device, "--quiet"]
started = time.time()
try:
    ran = subprocess.run(command, capture_output=True, text=True)
    code, stderr = ran.returncode, ran.stderr
except OSError as e:  # the posereg binary itself is missing
    code, stderr = 127, str(e)
status = {
    "status": "ok" if code == 0 else "failed",
    "exit_code": code,
    "seconds": round(time.time() - started, 1),
    "command": command,
    # posereg names the file and the problem on its last lines.
    "error": "\n".join(stderr.strip().splitlines()[-5:]) if code else "",
}
os.makedirs(os.path.dirname(a.status), exist_ok=True)
tmp = a.status + ".tmp"
with open(tmp, "w") as f:
    json.dump(status, f, indent=2)
os.replace(tmp, a.status)
