#include "run_settings.h"

#include <filesystem>
#include <fstream>
#include <sstream>

#include "atomic_file.h"
#include "error.h"
#include "walkthrough.h"

namespace dmmr {

namespace {
constexpr const char* kHeader = "dmmr run settings 1";

std::string number(double v) {
  std::ostringstream os;
  os.precision(17);
  os << v;
  return os.str();
}

std::string absolute(const std::string& p) {
  if (p.empty()) return p;  // none (a served run has no walkthrough)
  std::error_code ec;
  const std::filesystem::path abs = std::filesystem::absolute(p).lexically_normal();
  std::filesystem::path a = std::filesystem::weakly_canonical(abs, ec);
  return ec ? abs.string() : a.string();
}
}  // namespace

RunSettings baseRunSettings(const std::string& scene, const std::string& walkthrough,
                            const ViewOptions& view) {
  RunSettings s;
  s.add("scene", absolute(scene));
  s.add("walkthrough", absolute(walkthrough));
  s.add("width", std::to_string(view.width));
  s.add("height", std::to_string(view.height));
  s.add("fovy", number(view.fovy_deg));
  s.add("near", number(view.near));
  return s;
}

std::string formatRunSettings(const RunSettings& s) {
  std::string out = std::string(kHeader) + "\n";
  for (const auto& [name, value] : s.values) out += name + "=" + value + "\n";
  return out;
}

RunSettings parseRunSettings(const std::string& text, const std::string& path) {
  std::istringstream in(text);
  std::string line;
  if (!std::getline(in, line) || line != kHeader)
    throw Error(fileError(path, 1, std::string("expected \"") + kHeader + "\""));
  RunSettings s;
  for (long n = 2; std::getline(in, line); ++n) {
    size_t eq = line.find('=');
    if (eq == std::string::npos || eq == 0) throw Error(fileError(path, n, "expected NAME=VALUE"));
    s.add(line.substr(0, eq), line.substr(eq + 1));
  }
  return s;
}

void writeRunSettings(const std::string& dir, const RunSettings& s) {
  writeFileAtomic(dir + "/" + kRunSettingsFile, formatRunSettings(s));
}

void checkResume(const std::string& dir, const RunSettings& s, uint32_t from_frame) {
  const std::string path = dir + "/" + kRunSettingsFile;
  bool earlier = std::filesystem::exists(path);
  for (uint32_t f = 0; f < from_frame && !earlier; ++f)
    earlier = std::filesystem::exists(dir + "/" + frameFileName(f));
  if (!earlier) return;  // nothing there yet: frames from_frame on alone, mixing nothing
  for (uint32_t f = 0; f < from_frame; ++f)
    if (!std::filesystem::exists(dir + "/" + frameFileName(f)))
      throw Error(fileError(dir + "/" + frameFileName(f),
                            "missing, so --from-frame " + std::to_string(from_frame) +
                                " would leave a gap: resume from frame " + std::to_string(f) +
                                " or earlier"));
  if (!std::filesystem::exists(path))
    throw Error(fileError(path,
                          "missing: the frames there cannot be checked against this run's "
                          "settings; render from frame 0"));
  std::vector<uint8_t> bytes = readFileBytes(path);
  RunSettings was = parseRunSettings(std::string(bytes.begin(), bytes.end()), path);
  std::string diff;
  for (const auto& [name, value] : s.values) {
    std::string before = "(none)";
    for (const auto& [n, v] : was.values)
      if (n == name) before = v;
    if (before != value) diff += "; " + name + " was " + before + ", now " + value;
  }
  for (const auto& [n, v] : was.values) {
    bool known = false;
    for (const auto& kv : s.values) known = known || kv.first == n;
    if (!known) diff += "; " + n + " was " + v + ", now (none)";
  }
  if (!diff.empty())
    throw Error(fileError(path, "the earlier frames were made with other settings" + diff +
                                    ": resume with the same settings, or render from frame 0"));
}

}  // namespace dmmr
