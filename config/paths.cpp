// ${RUNTIME_DIR} / ${STATE_DIR} in config paths, so one config works under systemd
// (RuntimeDirectory=, StateDirectory=) and for a user running the daemon by hand.
#include <unistd.h>  // getuid

#include <cstdlib>  // getenv

#include "config/config.hpp"

namespace feedloop::config {
namespace {

std::string env(const char* name) {
  const char* v = std::getenv(name);
  return v != nullptr ? std::string(v) : std::string();
}

// systemd may pass several directories separated by ':'; the first is ours.
std::string first_of(const std::string& list) { return list.substr(0, list.find(':')); }

}  // namespace

PathVars path_vars_from_environment() {
  PathVars v;
  const std::string user_tmp = "/tmp/feedloop-" + std::to_string(::getuid());
  if (const std::string s = env("RUNTIME_DIRECTORY"); !s.empty()) {
    v.runtime_dir = first_of(s);
  } else if (const std::string x = env("XDG_RUNTIME_DIR"); !x.empty()) {
    v.runtime_dir = x + "/feedloop";
  } else {
    v.runtime_dir = user_tmp;
  }
  if (const std::string s = env("STATE_DIRECTORY"); !s.empty()) {
    v.state_dir = first_of(s);
  } else if (const std::string x = env("XDG_STATE_HOME"); !x.empty()) {
    v.state_dir = x + "/feedloop";
  } else if (const std::string h = env("HOME"); !h.empty()) {
    v.state_dir = h + "/.local/state/feedloop";
  } else {
    v.state_dir = user_tmp + "/state";
  }
  return v;
}

Result<std::string> expand_path(std::string_view path, const PathVars& vars) {
  std::string out;
  std::size_t i = 0;
  while (i < path.size()) {
    const std::size_t start = path.find("${", i);
    if (start == std::string_view::npos) {
      out.append(path.substr(i));
      break;
    }
    out.append(path.substr(i, start - i));
    const std::size_t end = path.find('}', start);
    if (end == std::string_view::npos)
      return Error{"unterminated '${' in path '" + std::string(path) + "'", {}};
    const std::string_view name = path.substr(start + 2, end - start - 2);
    if (name == "RUNTIME_DIR") {
      out += vars.runtime_dir;
    } else if (name == "STATE_DIR") {
      out += vars.state_dir;
    } else {
      return Error{"unknown variable ${" + std::string(name) +
                       "} in path (known: ${RUNTIME_DIR}, ${STATE_DIR})",
                   {}};
    }
    i = end + 1;
  }
  return out;
}

}  // namespace feedloop::config
