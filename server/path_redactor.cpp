#include "server/path_redactor.h"

#include <algorithm>
#include <cctype>

namespace probebake::server {
namespace fs = std::filesystem;

PathRedactor::PathRedactor(const fs::path& dataDir) {
  std::error_code ec;
  for (const fs::path& form :
       {dataDir, fs::absolute(dataDir, ec), fs::weakly_canonical(dataDir, ec)}) {
    std::string text = form.lexically_normal().string();
    while (text.size() > 1 && text.back() == '/') text.pop_back();
    // "." or "/" would rewrite every message.
    if (text.empty() || text == "." || text == "/") continue;
    if (std::find(prefixes_.begin(), prefixes_.end(), text) == prefixes_.end())
      prefixes_.push_back(std::move(text));
  }
  // The longest first: an absolute path contains the relative form as its tail.
  std::sort(prefixes_.begin(), prefixes_.end(),
            [](const std::string& a, const std::string& b) { return a.size() > b.size(); });
}

namespace {

// Characters of a path; a folder's name matches only where none precedes or follows it (but a
// separator may follow), so "data" is replaced in "open data/x" and not in "database".
bool IsPathChar(char c) {
  return std::isalnum(static_cast<unsigned char>(c)) || c == '/' || c == '.' || c == '_' ||
         c == '-' || c == '~' || c == '+';
}

std::string ReplaceFolder(const std::string& text, const std::string& folder) {
  std::string out;
  size_t from = 0;
  for (size_t at = text.find(folder); at != std::string::npos; at = text.find(folder, at + 1)) {
    const size_t end = at + folder.size();
    const bool starts = at == 0 || !IsPathChar(text[at - 1]);
    const bool ends = end == text.size() || text[end] == '/' || !IsPathChar(text[end]);
    if (!starts || !ends || at < from) continue;
    out.append(text, from, at - from);
    out += "DATA";
    from = end;
  }
  out.append(text, from, std::string::npos);
  return out;
}

}  // namespace

std::string PathRedactor::operator()(std::string_view message) const {
  std::string text(message);
  for (const std::string& prefix : prefixes_) text = ReplaceFolder(text, prefix);
  return text;
}

absl::Status PathRedactor::operator()(const absl::Status& status) const {
  if (status.ok() || prefixes_.empty()) return status;
  return absl::Status(status.code(), (*this)(std::string(status.message())));
}

}  // namespace probebake::server
