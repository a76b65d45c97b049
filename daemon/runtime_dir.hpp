// The channels' paths checked before anything is created in them: a socket or pty link belongs
// in the runtime directory, and that directory must not let other users plant or replace files.
//   error:   a directory on the way that is writable by everyone without the sticky bit (/tmp has
//            the bit; a 0777 directory does not: anyone could swap the socket for their own);
//            a path outside the runtime directory.
//   warning: a relative path (it depends on the daemon's working directory); a socket mode
//            wider than 0660 (other users could drive the printer).
#pragma once

#include <string>
#include <vector>

#include "core/result.hpp"

namespace feedloop::daemon {

// `path` of one channel, `runtime_dir` the runtime directory (${RUNTIME_DIR}), `mode` the
// socket's mode (0 for a pty link: not checked). Warnings are appended to `warnings`.
Status check_channel_path(const std::string& what, const std::string& path, const std::string& runtime_dir,
                          unsigned mode, std::vector<std::string>* warnings);

// Refuses a directory writable by everyone without the sticky bit (and any such parent).
Status check_directory_safe(const std::string& dir);

}  // namespace feedloop::daemon
