// What makes a run's frames what they are (scene, walkthrough, view, the
// options that change pixels), kept beside the frames so that a resumed run
// (--from-frame) cannot append frames made another way to the earlier ones.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "camera.h"

namespace dmmr {

struct RunSettings {
  std::vector<std::pair<std::string, std::string>> values;  // in order, names unique
  void add(const std::string& name, const std::string& value) { values.emplace_back(name, value); }
  friend bool operator==(const RunSettings&, const RunSettings&) = default;
};

inline constexpr const char* kRunSettingsFile = "run-settings.txt";

// The settings every run has: the scene and walkthrough (absolute paths) and
// the view (size, field of view, near plane). Callers add the options of
// their renderer that change pixels.
RunSettings baseRunSettings(const std::string& scene, const std::string& walkthrough,
                            const ViewOptions& view);

// "dmmr run settings 1" then one "name=value" line each.
std::string formatRunSettings(const RunSettings& s);
// Throws Error naming `path` (and the line) on anything else.
RunSettings parseRunSettings(const std::string& text, const std::string& path);

// `dir`/run-settings.txt, written atomically.
void writeRunSettings(const std::string& dir, const RunSettings& s);

// Before resuming into `dir` from frame `from_frame` (> 0). A directory with
// neither a settings file nor any of frames 0 to from_frame - 1 takes frames
// from_frame on alone (a part of a walkthrough rendered by itself). Otherwise
// frames 0 to from_frame - 1 are there (frameFileName) and the settings file
// equals `s`. Throws Error naming the first missing frame, a missing
// settings file, or each setting that differs (was, now).
void checkResume(const std::string& dir, const RunSettings& s, uint32_t from_frame);

}  // namespace dmmr
