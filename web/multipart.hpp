// multipart/form-data (RFC 7578) as the UIs upload files: POST /server/files/upload with the
// parts "file" (with a filename), "root", "path", "print". Parsing never throws and never
// reads outside the body; a malformed body is an error naming what is wrong.
#pragma once

#include <map>
#include <string>
#include <string_view>

#include "core/result.hpp"

namespace feedloop::web {

struct MultipartForm {
  std::map<std::string, std::string, std::less<>> fields;  // plain parts by name
  std::string file_name;                                   // the "file" part's filename
  std::string_view file;                                   // its bytes (a view into the body)
  bool has_file = false;
};

// `content_type`: the request's Content-Type header (holds the boundary).
Result<MultipartForm> parse_multipart(std::string_view content_type, std::string_view body);

}  // namespace feedloop::web
