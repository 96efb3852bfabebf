#!/usr/bin/python3
"""Installs the Python package conica the way a user would, into a venv under the build folder:

    /usr/bin/python3 -m venv --system-site-packages WORK/venv      (Debian's python3-zmq,
    WORK/venv/bin/python -m pip install --no-build-isolation ...    python3-protobuf, numpy)

from a copy of clients/python and proto/ in WORK/tree (so the build writes nothing into the
source tree), then checks the installed package: imported from the venv, with the protocol
modules its build step generated from proto/, their typed stubs and py.typed.

    /usr/bin/python3 tests/python/install_package.py --source . --work build/python
"""
import argparse
import os
import shutil
import subprocess
import sys
import time


def run(cmd, label=None, **kw):
    t0 = time.monotonic()
    r = subprocess.run(cmd, capture_output=True, text=True, **kw)
    print(f"$ {label or ' '.join(cmd)}  ({time.monotonic() - t0:.1f} s, exit {r.returncode})")
    if r.returncode != 0:
        sys.exit(f"FAIL: {cmd[0]} exited {r.returncode}:\n{r.stdout}\n{r.stderr}")
    return r


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--source", required=True, help="the repository")
    ap.add_argument("--work", required=True, help="folder for the copy and the venv")
    ap.add_argument("--python", default="/usr/bin/python3", help="the interpreter of the venv")
    args = ap.parse_args()
    work = os.path.abspath(args.work)
    tree = os.path.join(work, "tree")
    venv = os.path.join(work, "venv")
    shutil.rmtree(tree, ignore_errors=True)
    ignore = shutil.ignore_patterns("build", "*.egg-info", "__pycache__", "*_pb2.py", "*_pb2.pyi")
    shutil.copytree(os.path.join(args.source, "clients", "python"),
                    os.path.join(tree, "clients", "python"), ignore=ignore)
    shutil.copytree(os.path.join(args.source, "proto"), os.path.join(tree, "proto"), ignore=ignore)

    py = os.path.join(venv, "bin", "python")
    cfg = os.path.join(venv, "pyvenv.cfg")
    if not (os.path.exists(py) and "include-system-site-packages = true" in open(cfg).read()):
        shutil.rmtree(venv, ignore_errors=True)
        # --without-pip: the venv's pip is Debian's python3-pip, seen through the system site
        # packages (installing pip into every venv takes longer than the tests).
        run([args.python, "-m", "venv", "--system-site-packages", "--without-pip", venv])
    env = dict(os.environ)
    env.pop("PYTHONPATH", None)
    env["PIP_DISABLE_PIP_VERSION_CHECK"] = "1"
    run([py, "-m", "pip", "install", "--no-build-isolation", "--no-index", "--no-cache-dir",
         os.path.join(tree, "clients", "python")], env=env, cwd=work)
    check = ("import os, sys, conica, conica.aio, conica.v1.messages_pb2 as m\n"
             "d = os.path.dirname(conica.__file__)\n"
             "assert sys.prefix != sys.base_prefix, 'not a venv'\n"
             "assert d.startswith(sys.prefix), f'conica imported from {d}, not the venv'\n"
             "for f in ('py.typed', 'v1/messages_pb2.py', 'v1/messages_pb2.pyi', "
             "'v1/scene_pb2.py', 'v1/scene_pb2.pyi'):\n"
             "    assert os.path.isfile(os.path.join(d, f)), f'{f} not installed'\n"
             "assert m.ClientMessage(protocol_version=1).SerializeToString() == b'\\x08\\x01'\n"
             "print('installed:', d)\n")
    r = run([py, "-c", check], label=f"{py} -c <check the installed package>", env=env, cwd=work)
    print(r.stdout.strip())
    print("ok: conica installed into", venv)


if __name__ == "__main__":
    main()
