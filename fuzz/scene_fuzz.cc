// Scene loader on arbitrary text (protobuf text format -> validation -> build_model). Relative
// mesh paths resolve against a folder that does not exist, so inputs cannot reach real files.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "io/scene.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  auto r = conica::io::parse_scene(text, "fuzz.pbtxt", "nonexistent-fuzz-dir");
  (void)r.ok();
  return 0;
}
