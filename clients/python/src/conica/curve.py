"""CURVE keys in ZeroMQ certificates, the files pyzmq's zmq.auth.create_certificates and czmq's
zcert write (and conica-keygen, conica-server --generate-keys): NAME.key is the public
certificate, NAME.key_secret holds the public and the secret key. Old conica key files
("public <z85>" / "secret <z85>" lines, NAME.key secret) are refused with the command that
converts them."""
from __future__ import annotations

import os
from typing import Dict, List, NamedTuple, Union

import zmq
from zmq.utils import z85

from .errors import KeyFileError

PathLike = Union[str, "os.PathLike[str]"]


class CurveKeys(NamedTuple):
    """What a client needs to talk to a CURVE server (z85-encoded bytes): the server's public
    key, this client's public key and its secret key."""

    server_public: bytes
    public: bytes
    secret: bytes


def _valid_key(key: str) -> bool:
    try:
        return len(key) == 40 and len(z85.decode(key.encode())) == 32
    except (ValueError, KeyError, TypeError):
        return False


def _old_format(lines: List[str]) -> bool:
    words = [line.split() for line in lines if line.strip() and not line.strip().startswith("#")]
    return bool(words) and all(len(w) == 2 and w[0] in ("public", "secret") and _valid_key(w[1])
                               for w in words)


def read_key_file(path: PathLike) -> Dict[str, bytes]:
    """The keys of a ZeroMQ certificate as {"public": ..., "secret": ...} (z85 bytes; "secret"
    only in a secret certificate); KeyFileError names the file, the line and the problem."""
    try:
        with open(path, encoding="ascii", errors="replace") as f:
            lines = f.read().splitlines()
    except OSError as e:
        raise KeyFileError(f"{path}: cannot open key file ({e.strerror})") from None
    if _old_format(lines):
        raise KeyFileError(
            f"{path}: an old conica key file ('public <z85>' / 'secret <z85>' lines, in which "
            "NAME.key was the SECRET file and NAME.pub the public one); conica now reads ZeroMQ "
            "certificates as pyzmq and czmq write them (NAME.key public, NAME.key_secret "
            f"secret): convert it with `conica-keygen --convert {path}`")
    keys: Dict[str, bytes] = {}
    section = ""
    for n, line in enumerate(lines[:1000], start=1):
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        indent = len(line) - len(line.lstrip(" "))
        if indent == 0:
            section = stripped.split()[0]
            continue
        name, eq, value = stripped.partition("=")
        name = name.strip()
        if section != "curve" or indent != 4 or name not in ("public-key", "secret-key"):
            continue
        value = value.strip()
        if value[:1] in ("\"", "'") and value.find(value[0], 1) > 0:
            value = value[1:value.find(value[0], 1)]
        else:
            value = value.split("#")[0].strip()
        if not eq or not _valid_key(value):
            raise KeyFileError(f"{path}:{n}: {name} is not a z85 CURVE key "
                               "(40 characters of Z85 for 32 bytes)")
        keys[name.split("-")[0]] = value.encode()
    if "public" not in keys:
        raise KeyFileError(f"{path}: no curve/public-key in the file (a ZeroMQ certificate has a "
                           "'curve' section with public-key = \"<z85>\")")
    if "secret" in keys and zmq.curve_public(keys["secret"]) != keys["public"]:
        raise KeyFileError(f"{path}: public and secret keys do not match")
    return keys


def curve_keys(server_pub_file: PathLike, key_file: PathLike) -> CurveKeys:
    """The keys for a CURVE client from the server's public certificate (its NAME.key) and this
    client's secret certificate (its NAME.key_secret)."""
    if not zmq.has("curve"):
        raise KeyFileError("CURVE requested but this libzmq has no CURVE support")
    try:
        server = read_key_file(server_pub_file)
    except KeyFileError as e:
        raise KeyFileError(f"{e} (--curve-server-pub: the server's public certificate "
                           "NAME.key)") from None
    if "secret" in server:
        raise KeyFileError(f"{server_pub_file}: holds the server's secret key; give the client "
                           "the server's public certificate (NAME.key, not NAME.key_secret)")
    try:
        mine = read_key_file(key_file)
    except KeyFileError as e:
        raise KeyFileError(f"{e} (--curve-key: this client's secret certificate "
                           "NAME.key_secret)") from None
    if "secret" not in mine:
        raise KeyFileError(f"{key_file}: a public certificate (no secret key); give this "
                           "client's secret certificate (NAME.key_secret), not its NAME.key")
    return CurveKeys(server["public"], mine["public"], mine["secret"])
