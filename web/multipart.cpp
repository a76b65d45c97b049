#include "web/multipart.hpp"

#include <algorithm>
#include <cctype>

namespace feedloop::web {

namespace {
std::string lower(std::string_view s) {
  std::string o(s);
  for (char& c : o) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return o;
}
// The value of `name=` in a header's parameters (quoted or not).
std::string param(std::string_view header, std::string_view name) {
  const std::string lh = lower(header);
  size_t at = 0;
  while ((at = lh.find(name, at)) != std::string::npos) {
    const bool starts = at == 0 || lh[at - 1] == ';' || lh[at - 1] == ' ';
    const size_t eq = at + name.size();
    if (starts && eq < lh.size() && lh[eq] == '=') {
      size_t v = eq + 1;
      if (v < header.size() && header[v] == '"') {
        const size_t end = header.find('"', v + 1);
        if (end == std::string_view::npos) return {};
        return std::string(header.substr(v + 1, end - v - 1));
      }
      size_t end = header.find(';', v);
      if (end == std::string_view::npos) end = header.size();
      std::string_view val = header.substr(v, end - v);
      while (!val.empty() && val.back() == ' ') val.remove_suffix(1);
      return std::string(val);
    }
    at = eq;
  }
  return {};
}
}  // namespace

Result<MultipartForm> parse_multipart(std::string_view content_type, std::string_view body) {
  if (lower(content_type).rfind("multipart/form-data", 0) != 0)
    return Error{"expected Content-Type multipart/form-data"};
  const std::string boundary = param(content_type, "boundary");
  if (boundary.empty() || boundary.size() > 200)
    return Error{"multipart: no valid boundary in the Content-Type"};
  const std::string delim = "--" + boundary;
  MultipartForm form;
  size_t pos = body.find(delim);
  if (pos == std::string_view::npos) return Error{"multipart: the body has no boundary line"};
  int parts = 0;
  while (true) {
    pos += delim.size();
    if (body.substr(pos, 2) == "--") break;  // the closing delimiter
    if (body.substr(pos, 2) != "\r\n")
      return Error{"multipart: expected CRLF after the boundary at byte " + std::to_string(pos)};
    pos += 2;
    const size_t head_end = body.find("\r\n\r\n", pos);
    if (head_end == std::string_view::npos)
      return Error{"multipart: a part's headers do not end (byte " + std::to_string(pos) + ")"};
    const std::string_view headers = body.substr(pos, head_end - pos);
    const size_t data_begin = head_end + 4;
    const size_t next = body.find("\r\n" + delim, data_begin);
    if (next == std::string_view::npos)
      return Error{"multipart: a part has no closing boundary (byte " + std::to_string(pos) + ")"};
    if (++parts > 64) return Error{"multipart: more than 64 parts"};
    std::string name, filename;
    bool has_filename = false;
    size_t hb = 0;
    while (hb <= headers.size()) {
      size_t he = headers.find("\r\n", hb);
      if (he == std::string_view::npos) he = headers.size();
      const std::string_view h = headers.substr(hb, he - hb);
      if (lower(h.substr(0, 20)) == "content-disposition:") {
        name = param(h, "name");
        has_filename = lower(h).find("filename=") != std::string::npos;
        filename = param(h, "filename");
      }
      hb = he + 2;
    }
    const std::string_view data = body.substr(data_begin, next - data_begin);
    if (name == "file" && has_filename) {
      form.has_file = true;
      form.file_name = filename;
      form.file = data;
    } else if (!name.empty()) {
      if (data.size() > 4096)
        return Error{"multipart: field '" + name + "' is longer than 4096 bytes"};
      form.fields[name] = std::string(data);
    }
    pos = next + 2;
  }
  return form;
}

}  // namespace feedloop::web
