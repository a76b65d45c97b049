// Writing a whole file so that a reader sees the old file or the new one, never half of one,
// also after a power cut: a temporary file beside it (mkstemp), written, flushed to the disk
// (fsync), then renamed over it. On any failure the temporary is removed and the old file stays.
#pragma once

#include <sys/types.h>

#include <string>
#include <string_view>

#include "core/result.hpp"

namespace feedloop {

// Errors: "cannot create a file in DIR: why", "cannot write PATH: why", "cannot rename over
// PATH: why" (errno's text).
Status write_file_atomically(const std::string& path, std::string_view data, mode_t mode = 0644);

}  // namespace feedloop
