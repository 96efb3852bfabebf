"""CURVE key files as written by `conica-server --generate-keys DIR --key-name NAME`: lines
"public <z85>" and "secret <z85>", '#' comments."""
from __future__ import annotations

import os
from typing import Dict, NamedTuple, Union

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


def read_key_file(path: PathLike) -> Dict[str, bytes]:
    """The keys of a conica key file as {"public": ..., "secret": ...} (z85 bytes); KeyFileError
    names the file, the line and the problem."""
    try:
        with open(path, encoding="ascii", errors="replace") as f:
            lines = f.read().splitlines()
    except OSError as e:
        raise KeyFileError(f"{path}: cannot open key file ({e.strerror})") from None
    keys: Dict[str, bytes] = {}
    for n, line in enumerate(lines[:100], start=1):
        words = line.split()
        if not words or words[0].startswith("#"):
            continue
        ok = len(words) >= 2 and words[0] in ("public", "secret") and len(words[1]) == 40
        if ok:
            try:
                ok = len(z85.decode(words[1].encode())) == 32
            except (ValueError, KeyError, TypeError):
                ok = False
        if not ok:
            raise KeyFileError(f"{path}:{n}: expected 'public <z85 key>' or 'secret <z85 key>'")
        keys[words[0]] = words[1].encode()
    if not keys:
        raise KeyFileError(f"{path}: no key in the file")
    if "secret" in keys:
        public = zmq.curve_public(keys["secret"])
        if keys.setdefault("public", public) != public:
            raise KeyFileError(f"{path}: public and secret keys do not match")
    return keys


def curve_keys(server_pub_file: PathLike, key_file: PathLike) -> CurveKeys:
    """The keys for a CURVE client from the server's .pub file and this client's .key file."""
    if not zmq.has("curve"):
        raise KeyFileError("CURVE requested but this libzmq has no CURVE support")
    try:
        server = read_key_file(server_pub_file)
    except KeyFileError as e:
        raise KeyFileError(f"{e} (--curve-server-pub: the server's .pub file)") from None
    if "secret" in server:
        raise KeyFileError(f"{server_pub_file}: holds the server's secret key; "
                           "give the client the server's .pub file")
    try:
        mine = read_key_file(key_file)
    except KeyFileError as e:
        raise KeyFileError(f"{e} (--curve-key: this client's .key file)") from None
    if "secret" not in mine:
        raise KeyFileError(f"{key_file}: no secret key; give this client's .key file "
                           "(public and secret), not its .pub")
    return CurveKeys(server["public"], mine["public"], mine["secret"])
