"""The generated protocol module, with a clear message when the package was not built."""
try:
    from .v1 import messages_pb2 as pb
except ImportError as e:  # pragma: no cover - only without the build step
    raise ImportError(
        "conica.v1.messages_pb2 is missing: it is generated from proto/conica/v1/messages.proto "
        "when the package is built; install it with `pip install --no-build-isolation "
        "clients/python` (protoc from Debian's protobuf-compiler) instead of importing the "
        f"source folder ({e})") from e

__all__ = ["pb"]
