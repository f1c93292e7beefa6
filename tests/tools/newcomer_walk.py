#!/usr/bin/env python3
"""A newcomer's walk through README.md (issue 43): every command of the appliance block and
every runnable row of the "What runs today" table, pasted in order, on the simulator (no camera)
and the shared data. Each must exit 0, and nothing it prints may name an internal field (an
options struct, a C++ scope, a JSON library's exception, an abort).

What the walk changes in a pasted command, and only that:
- paths: build/bin -> the build's bin, ../shared/data -> $MOCAP_DATA_DIR, /var/lib/mocap -> a
  temporary state folder; localhost:9870/9871 -> the ports the walk's mocapd listens on;
- mocapd runs in the background with that state folder, a folder with no camera and free
  ports; `nc` reads 5 lines of the stream, `curl` and `xdg-open` are a GET of the path;
  `mocap take` gets --box with the walk's port and --state-dir (the default's stand-in);
  --vmc sends to this machine;
- a recording runs 20 frames (--frames 20), not the whole clip.
A table row with a placeholder (FILE, DIR, N, a|b choice) is not runnable as written and is
skipped; its name is printed.

usage: newcomer_walk.py BIN_DIR SOURCE_DIR   (MOCAP_DATA_DIR: the shared data; without it the
data rows are skipped and said so). Exit 0: every command passed; 1: a failure (printed).
"""
import os
import re
import shlex
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request

BIN, SRC = sys.argv[1], sys.argv[2]
DATA = os.environ.get("MOCAP_DATA_DIR", "")
# What a user must never read: the code's own names and failures.
INTERNAL = [
    (re.compile(r"\b[A-Z][A-Za-z]*Options\b"), "an options struct"),
    (re.compile(r"\b(std|mocap|nlohmann)::"), "a C++ scope"),
    (re.compile(r"\[json\.exception"), "a JSON library exception"),
    (re.compile(r"field \""), "a struct field"),
    (re.compile(r"terminate called|Assertion .* failed|Segmentation fault|AddressSanitizer"),
     "an abort"),
]
failures = []


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def check_text(what, text):
    for line in text.splitlines():
        for pattern, kind in INTERNAL:
            if pattern.search(line):
                failures.append(f"{what}: names {kind}: {line.strip()[:200]}")


def run(what, argv, env=None, timeout=300):
    t0 = time.monotonic()
    r = subprocess.run(argv, capture_output=True, text=True, errors="replace", timeout=timeout,
                       env=env)
    out = r.stdout + r.stderr
    print(f"[walk] {r.returncode} {time.monotonic() - t0:5.1f} s  {what}", flush=True)
    if r.returncode != 0:
        failures.append(f"{what}: exit {r.returncode}\n{out[-2000:]}")
    check_text(what, out)
    return r


def http_get(port, path):
    with urllib.request.urlopen(f"http://127.0.0.1:{port}{path}", timeout=30) as r:
        return r.status, r.read()


class Mocapd:
    """build/bin/mocapd in the background, as the README starts it."""

    def __init__(self, args, state, dev):
        self.stream, self.http = free_port(), free_port()
        argv = [f"{BIN}/mocapd"] + args + ["--state-dir", state, "--dev-dir", dev,
                                           "--stream-port", str(self.stream),
                                           "--http-port", str(self.http),
                                           "--bind-address", "127.0.0.1"]
        self.log = tempfile.TemporaryFile(mode="w+")
        self.proc = subprocess.Popen(argv, stdout=self.log, stderr=subprocess.STDOUT)
        for _ in range(300):
            try:
                if http_get(self.http, "/health")[0] == 200:
                    return
            except OSError:
                time.sleep(0.1)
        raise RuntimeError("mocapd did not answer /health in 30 s")

    def stop(self, what):
        self.proc.terminate()
        code = self.proc.wait(timeout=30)
        self.log.seek(0)
        text = self.log.read()
        print(f"[walk] {code}         {what} (stopped by SIGTERM)", flush=True)
        if code != 0:
            failures.append(f"{what}: exit {code}\n{text[-2000:]}")
        check_text(what, text)


def block_commands(readme):
    """The commands of the first code block after '## The appliance'."""
    part = readme.split("## The appliance", 1)[1].split("```sh", 1)[1].split("```", 1)[0]
    return [line.split("  #", 1)[0].strip() for line in part.splitlines() if line.strip()]


def table_commands(readme):
    part = readme.split("## What runs today", 1)[1].split("\n## ", 1)[0]
    cmds = []
    for line in part.splitlines():
        m = re.match(r"\| `([^`]+)`", line)
        if m:
            cmds.append(m.group(1).replace("\\|", "|"))
    return cmds


def paths(cmd, state):
    cmd = cmd.replace("build/bin/", BIN + "/").replace("../shared/data", DATA or "/nonexistent")
    return cmd.replace("/var/lib/mocap", state)


def walk_block(cmds, state, dev, work):
    box = None
    for cmd in cmds:
        words = shlex.split(paths(cmd, state))
        exe = os.path.basename(words[0])
        if exe == "mocapd" and len(words) == 1:
            box = Mocapd([], state, dev)
            time.sleep(3)
        elif exe == "mocapd" and "--recording" in words:
            if not DATA:
                print(f"[walk] skip  {cmd} (no MOCAP_DATA_DIR)")
                continue
            args = words[1:] + ["--frames", "20", "--state-dir", os.path.join(work, "rec_state"),
                                "--dev-dir", dev, "--stream-port", "0", "--http-port", "0"]
            run(cmd, [words[0]] + args, timeout=600)
        elif exe == "mocapd" and "--vmc" in words:
            target = f"127.0.0.1:{free_port()}"
            args = ["--vmc", target, "--frames", "60", "--state-dir", state, "--dev-dir", dev,
                    "--stream-port", "0", "--http-port", "0"]
            run(cmd, [words[0]] + args)
        elif exe == "nc":
            with socket.create_connection(("127.0.0.1", box.stream), timeout=30) as s:
                data = b""
                while data.count(b"\n") < 5:
                    chunk = s.recv(65536)
                    if not chunk:
                        break
                    data += chunk
            lines = data.count(b"\n")
            print(f"[walk] {0 if lines >= 5 else 1}         {cmd} ({lines} lines)")
            if lines < 5:
                failures.append(f"{cmd}: the stream gave {lines} lines")
        elif exe in ("curl", "xdg-open"):
            path = "/" + words[1].split("/", 1)[1] if "/" in words[1].split("//")[-1] else "/"
            status, body = http_get(box.http, path if exe == "curl" else "/")
            print(f"[walk] {status}       {cmd} ({len(body)} bytes)")
            if status != 200:
                failures.append(f"{cmd}: HTTP {status}")
            check_text(cmd, body.decode("utf-8", "replace"))
        elif exe == "mocap" and words[1] == "take":
            # The box's state folder is the walk's, not the default /var/lib/mocap (its token).
            at = ["--box", str(box.http), "--state-dir", state]
            run(cmd, words + at)
            if words[2] == "start":
                time.sleep(2)
                run("mocap take stop", [words[0], "take", "stop"] + at)
                run("mocap take list", [words[0], "take", "list"] + at)
                time.sleep(2)  # the take's exports are written in the background
        elif exe == "mocap" and words[1] == "export":
            out = [w if not w.endswith("walk1/") else os.path.join(work, "walk1/") for w in words]
            run(cmd, out)
        else:
            run(cmd, words)
    if box is not None:
        box.stop("build/bin/mocapd")


def runnable(cmd):
    """A table row as written: no placeholder left once the optional [...] parts are dropped."""
    cmd = re.sub(r"\s*\[[^\]]*\]", "", cmd)
    if "/ `" in cmd or " | " in cmd or "|" in cmd:
        return None
    if re.search(r"\b(FILE|DIR|N|P|F|S|K|H|L|PHOTO|REFERENCE|GLOB\w*|SPEC|A,B)\b", cmd):
        return None
    if "model.json" in cmd or "/dev/video" in cmd:
        return None
    return cmd


def walk_table(cmds, state):
    for cmd in cmds:
        plain = runnable(cmd)
        if plain is None:
            print(f"[walk] skip  {cmd[:100]} (a placeholder: not runnable as written)")
            continue
        if "/shared/data" in plain and not DATA:
            print(f"[walk] skip  {plain} (no MOCAP_DATA_DIR)")
            continue
        env = dict(os.environ)
        words = shlex.split(paths(plain, state))
        while "=" in words[0] and not words[0].startswith("/"):
            k, v = words.pop(0).split("=", 1)
            env[k] = v
        if "--recording" in words and os.path.basename(words[0]) == "mocap":
            words += ["--frames", "20"]
        run(plain, words, env=env, timeout=600)


def main():
    readme = open(os.path.join(SRC, "README.md"), encoding="utf-8").read()
    os.chdir(SRC)  # the README's paths are the repository's (models/, build/bin)
    with tempfile.TemporaryDirectory(prefix="mocap_walk_") as work:
        state, dev = os.path.join(work, "state"), os.path.join(work, "dev")
        os.makedirs(dev)
        walk_block(block_commands(readme), state, dev, work)
        walk_table(table_commands(readme), state)
    print(f"[walk] {len(failures)} failures")
    for f in failures:
        print("FAILED:", f)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
