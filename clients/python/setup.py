"""The build step of the conica package: conica/v1/*_pb2.py and their typed stubs (*_pb2.pyi) are
generated from the protocol files (proto/conica/v1/*.proto) with protoc while the package is
built; everything else is in pyproject.toml.

protoc: $PROTOC, else `protoc` on PATH (Debian: protobuf-compiler). The .proto files: $CONICA_PROTO_DIR,
else proto/ beside this file (an sdist), else the repository's proto/ two folders up."""
import os
import shutil
import subprocess
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = Path(__file__).resolve().parent
PROTOS = ["conica/v1/messages.proto", "conica/v1/scene.proto"]


def proto_dir() -> Path:
    candidates = [os.environ.get("CONICA_PROTO_DIR"), HERE / "proto", HERE.parent.parent / "proto"]
    for c in candidates:
        if c and all((Path(c) / p).is_file() for p in PROTOS):
            return Path(c)
    raise SystemExit("conica build: cannot find proto/conica/v1/messages.proto (looked in "
                     + ", ".join(str(c) for c in candidates if c)
                     + "); build from the conica repository or set CONICA_PROTO_DIR")


def protoc() -> str:
    found = os.environ.get("PROTOC") or shutil.which("protoc")
    if not found:
        raise SystemExit("conica build: protoc not found (Debian: apt-get install "
                         "protobuf-compiler; or set PROTOC)")
    return found


class BuildWithProtocol(build_py):
    """build_py, then protoc --python_out --pyi_out into the built package (or into src/ for an
    editable install)."""

    def run(self) -> None:
        super().run()
        out = HERE / "src" if getattr(self, "editable_mode", False) else Path(self.build_lib)
        src = proto_dir()
        cmd = [protoc(), f"--proto_path={src}", f"--python_out={out}", f"--pyi_out={out}",
               *[str(src / p) for p in PROTOS]]
        self.announce("running " + " ".join(cmd), level=2)
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode != 0:
            raise SystemExit(f"conica build: protoc failed ({r.returncode}):\n{r.stderr}")
        self._generated = [str(out / p.replace(".proto", f"_pb2{ext}"))
                           for p in PROTOS for ext in (".py", ".pyi")]
        missing = [g for g in self._generated if not os.path.isfile(g)]
        if missing:
            raise SystemExit("conica build: protoc did not write " + ", ".join(missing))

    def get_outputs(self, include_bytecode: bool = True):  # type: ignore[override]
        return list(super().get_outputs(include_bytecode)) + list(getattr(self, "_generated", []))


setup(cmdclass={"build_py": BuildWithProtocol})
