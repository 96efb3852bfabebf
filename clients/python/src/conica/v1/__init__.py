"""The conica.v1 protocol modules, generated from proto/conica/v1/*.proto by the package's build
step (protoc --python_out --pyi_out): messages_pb2 (the wire protocol) and scene_pb2 (scenes)."""
