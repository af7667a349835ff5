#!/usr/bin/env python3
# v4r - robust model-based object tracking. MIT licence.
"""Runs the shell commands of README.md as written, in a fresh folder.

Every ```sh block is read; `\\` continuations are joined and `# ...` comments dropped. `make`
lines (the build itself) are skipped; `build/bin/v4r` is the v4r under test. A block that starts
`v4r serve` is the service example: the server is started in the background (on free ports
instead of 5757 / 8080, so that tests can run side by side) and the lines after `nc HOST PORT` are
sent by a Python client, each answered OK; after `Start` an ObjectPose event must arrive.

usage: readme_commands.py --v4r build/bin/v4r --readme README.md
"""

import argparse
import os
import re
import shlex
import socket
import subprocess
import sys
import tempfile
import time


def blocks(readme):
    out, cur = [], None
    for line in open(readme, encoding="utf-8"):
        if cur is None and line.strip() == "```sh":
            cur = []
        elif cur is not None and line.strip() == "```":
            out.append(cur)
            cur = None
        elif cur is not None:
            cur.append(line.rstrip("\n"))
    return out


def strip_comment(line):
    """The line without a trailing `# comment` outside quotes."""
    quote = None
    for i, ch in enumerate(line):
        if quote:
            if ch == quote:
                quote = None
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and (i == 0 or line[i - 1] in " \t"):
            return line[:i].rstrip()
    return line.rstrip()


def commands(block):
    cmds, cur = [], ""
    for raw in block:
        line = strip_comment(raw)
        if line.endswith("\\"):
            cur += line[:-1] + " "
            continue
        cur += line
        if cur.strip():
            cmds.append(cur.strip())
        cur = ""
    return cmds


def run_shell(cmd, v4r, cwd):
    shell = cmd.replace("build/bin/v4r", shlex.quote(v4r))
    print(f"$ {cmd}", flush=True)
    t0 = time.time()
    r = subprocess.run(shell, shell=True, cwd=cwd, capture_output=True, text=True, timeout=900)
    sys.stdout.write(r.stdout[-2000:])
    sys.stdout.write(r.stderr[-2000:])
    print(f"  -> exit {r.returncode} in {time.time() - t0:.1f} s", flush=True)
    if r.returncode != 0:
        raise SystemExit(f"README command failed (exit {r.returncode}): {cmd}")


def serve_example(cmds, v4r, cwd):
    server_cmd = cmds[0]
    nc = next(i for i, c in enumerate(cmds) if c.startswith("nc "))
    protocol = cmds[nc + 1:]
    args = shlex.split(server_cmd.replace("build/bin/v4r", v4r))
    args = ["0" if a in ("8080",) else a for a in args] + ["--port", "0"]
    print(f"$ {server_cmd}   (on free ports)", flush=True)
    srv = subprocess.Popen(args, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        first = srv.stdout.readline()
        print("  " + first.strip(), flush=True)
        m = re.search(r"protocol on [^:]+:(\d+)", first)
        if not m:
            raise SystemExit("v4r serve did not say its port: " + first)
        port = int(m.group(1))
        sock = socket.create_connection(("127.0.0.1", port), timeout=20)
        f = sock.makefile("rb")
        hello = f.readline().decode().strip()
        print(f"  < {hello}")
        if not hello.startswith("Hello "):
            raise SystemExit("no Hello from v4r serve: " + hello)
        for line in protocol:
            print(f"  > {line}")
            sock.sendall((line + "\n").encode())
            while True:
                reply = f.readline().decode().strip()
                if not reply:
                    raise SystemExit("connection closed after: " + line)
                if reply.startswith("OK ") or reply.startswith("ERR "):
                    break
            print(f"  < {reply}")
            if not reply.startswith("OK "):
                raise SystemExit(f"README protocol line answered {reply}: {line}")
        deadline = time.time() + 30
        while time.time() < deadline:
            ev = f.readline().decode().strip()
            if ev.startswith("ObjectPose "):
                print(f"  < {ev[:120]}")
                if "status=lost" in ev:
                    raise SystemExit("the README's serve example loses the object: " + ev)
                break
        else:
            raise SystemExit("no ObjectPose event within 30 s")
        sock.sendall(b"Quit\n")
        sock.close()
    finally:
        srv.terminate()
        try:
            srv.wait(timeout=10)
        except subprocess.TimeoutExpired:
            srv.kill()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--v4r", required=True)
    ap.add_argument("--readme", required=True)
    a = ap.parse_args()
    v4r = os.path.abspath(a.v4r)
    ran = 0
    with tempfile.TemporaryDirectory(prefix="v4r_readme_") as cwd:
        for block in blocks(a.readme):
            cmds = commands(block)
            if not cmds or not cmds[0].startswith("build/bin/v4r") and not cmds[0].startswith("make"):
                continue  # pseudo-code, module graphs
            if cmds[0].startswith("build/bin/v4r serve"):
                serve_example(cmds, v4r, cwd)
                ran += 1
                continue
            for c in cmds:
                if c.startswith("make "):
                    print(f"(skipped: {c})")
                    continue
                run_shell(c, v4r, cwd)
                ran += 1
    if ran < 5:
        raise SystemExit(f"only {ran} README commands found: has the README changed its layout?")
    print(f"{ran} README commands ran")


if __name__ == "__main__":
    main()
