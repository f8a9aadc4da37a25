// Command-line options shared by the tools that render a walkthrough, so
// that every renderer of a run is told the same things the same way.
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <iterator>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <string>

#include "camera.h"

namespace dmmr {

// CLI::Range(lo, hi) for a double that also refuses NaN (which compares
// false with both bounds, so CLI::Range lets it through).
inline CLI::Validator finiteRange(double lo, double hi) {
  return CLI::Validator(
      [lo, hi](std::string& v) -> std::string {
        double x = 0;
        try {
          size_t used = 0;
          x = std::stod(v, &used);
          if (used != v.size()) return "'" + v + "' is not a number";
        } catch (const std::exception&) {
          return "'" + v + "' is not a number";
        }
        if (!(x >= lo && x <= hi))
          return "Value " + v + " not in range " + CLI::detail::to_string(lo) + " to " +
                 CLI::detail::to_string(hi);
        return {};
      },
      "FLOAT in [" + CLI::detail::to_string(lo) + " - " + CLI::detail::to_string(hi) + "]");
}

struct RunPaths {
  std::string scene, walkthrough, out, stats;
};

// --scene, --walkthrough, --out (required unless `path_optional`: the
// caller then checks them), --stats, and the view: --width, --height,
// --fovy, --near.
inline void addRunOptions(CLI::App& app, RunPaths& paths, ViewOptions& view,
                          bool path_optional = false) {
  app.add_option("--scene", paths.scene, "preprocessed scene directory")->required();
  app.add_option("--walkthrough", paths.walkthrough, "AnimationPath file")
      ->required(!path_optional);
  app.add_option("--out", paths.out, "output directory for frame_NNNNNN.png")
      ->required(!path_optional);
  app.add_option("--stats", paths.stats, "per-frame statistics CSV");
  app.add_option("--width", view.width, "image width")->check(CLI::Range(1, 16384));
  app.add_option("--height", view.height, "image height")->check(CLI::Range(1, 16384));
  app.add_option("--fovy", view.fovy_deg, "vertical field of view, degrees")
      ->check(finiteRange(1.0, 179.0));
  app.add_option("--near", view.near, "near plane distance (default: scene diagonal * 1e-5)")
      ->check(CLI::PositiveNumber);
}

// --NAME on|off into `*value`, which holds the default (appended to `help`).
inline void addSwitchOption(CLI::App& app, const std::string& name, bool* value,
                            const std::string& help) {
  app.add_option_function<std::string>(
         name, [value](const std::string& v) { *value = v == "on"; },
         help + " (default " + (*value ? "on" : "off") + ")")
      ->check(CLI::IsMember({"on", "off"}));
}

// --keep-freed-memory on|off into `*keep`, --huge-pages on|off into `*huge`
// (both default on) and --pre-touch auto|off|MiB into `*pre_touch_mib` (-1
// auto, the default; 0 off): the memory policy the tool applies at start-up
// (applyMemoryPolicy) and the heap it pre-touches once its scene is loaded
// (preTouchHeap; memory_policy.h).
inline void addMemoryOptions(CLI::App& app, bool* keep, bool* huge, int64_t* pre_touch_mib) {
  addSwitchOption(app, "--keep-freed-memory", keep,
                  "keep freed memory in malloc's heaps for reuse rather than return it to the "
                  "kernel, so that each frame does not page-fault its buffers in afresh; "
                  "resident memory stays at its peak");
  addSwitchOption(app, "--huge-pages", huge,
                  "back malloc's heap with transparent huge pages where the kernel gives them on "
                  "request, so that memory touched for the first time faults 2 MiB at a time, "
                  "not 4 KiB (the program restarts itself once with glibc.malloc.hugetlb=1 "
                  "added to GLIBC_TUNABLES; a value set there already stands)");
  app.add_option_function<std::string>(
         "--pre-touch",
         [pre_touch_mib](const std::string& v) {
           *pre_touch_mib = v == "auto" ? -1 : v == "off" ? 0 : std::stoll(v);
         },
         "touch this many MiB of heap once the scene is loaded, so that the caches grow into "
         "memory already mapped instead of faulting it in frame by frame (auto, the default: "
         "twice the scene's geometry files plus 16 MiB, at most 192; off; or MiB, at most 192; "
         "needs --keep-freed-memory on)")
      ->check([](const std::string& v) {
        if (v == "auto" || v == "off") return std::string();
        char* end = nullptr;
        long long n = std::strtoll(v.c_str(), &end, 10);
        if (v.empty() || *end || n < 0 || n > 192)
          return std::string("expected auto, off or MiB from 0 to 192");
        return std::string();
      });
}

// --flush-triangles auto|N into `*triangles` (-1 for auto): how the
// renderer flushes its drawing (Renderer::setFlushEvery; auto: the driver's
// default, defaultFlushTriangles). `*triangles` holds the tool's default.
inline void addFlushOption(CLI::App& app, int64_t* triangles) {
  std::string fallback = *triangles < 0 ? "auto" : std::to_string(*triangles);
  app.add_option_function<std::string>(
         "--flush-triangles",
         [triangles](const std::string& v) { *triangles = v == "auto" ? -1 : std::stoll(v); },
         "flush the drawing after N triangles, then after 2N more, then every 4N, from each "
         "frame and readback on, so that a CPU rasteriser bins one batch while it rasterises "
         "the last "
         "(auto: 4096 on llvmpipe and softpipe, 0 elsewhere; 0: never; default " +
             fallback + "); never changes a pixel")
      ->check([](const std::string& v) {
        if (v == "auto") return std::string();
        size_t digits = v.find_first_not_of("0123456789");
        return !v.empty() && digits == std::string::npos && v.size() <= 12
                   ? std::string()
                   : std::string("auto or a count of triangles");
      });
}

// --triangle-cull auto|on|off into *mode (-1, 1, 0): Renderer::setTriangleCull.
inline void addTriangleCullOption(CLI::App& app, int* mode) {
  std::string fallback = *mode < 0 ? "auto" : *mode ? "on" : "off";
  app.add_option_function<std::string>(
         "--triangle-cull",
         [mode](const std::string& v) { *mode = v == "auto" ? -1
                                                : v == "on" ? 1
                                                            : 0; },
         "drop, before each draw of a dense object, the triangles that cover no pixel centre "
         "of the region (auto: on with llvmpipe and softpipe, off elsewhere; default " +
             fallback + "); never changes a pixel")
      ->check(CLI::IsMember({"auto", "on", "off"}));
}

// --config FILE: a run config (TOML or INI) with the options' long names as
// keys; the command line overrides it. Unknown keys are errors, not
// silently ignored settings.
// CLI11's TOML/INI reader, with the checks it leaves out, each a
// CLI::ConfigError naming the line (exitParse adds the file): a string
// without its closing quote (CLI11 took the quote into the value), a
// [table] (run configs are flat), a key set twice, a line without NAME =
// VALUE, and a flag given anything but true or false (CLI11 took any word).
// Bare INI words stay values, as before.
class StrictConfig : public CLI::ConfigTOML {
 public:
  explicit StrictConfig(const CLI::App* app) : app_(app) {}
  std::vector<CLI::ConfigItem> from_config(std::istream& input) const override {
    std::string text((std::istreambuf_iterator<char>(input)), std::istreambuf_iterator<char>());
    check(text);
    std::istringstream again(text);
    return CLI::ConfigTOML::from_config(again);
  }

 private:
  [[noreturn]] static void fail(long line, const std::string& what) {
    throw CLI::ConfigError("line " + std::to_string(line) + ": " + what);
  }
  // The end of a quoted string starting at s[0], or npos.
  static size_t closingQuote(const std::string& s) {
    const char q = s[0];
    for (size_t i = 1; i < s.size(); ++i) {
      if (q == '"' && s[i] == '\\') {
        ++i;
        continue;
      }
      if (s[i] == q) return i;
    }
    return std::string::npos;
  }
  void check(const std::string& text) const {
    std::istringstream in(text);
    std::map<std::string, long> seen;
    std::string raw;
    for (long n = 1; std::getline(in, raw); ++n) {
      const std::string line = CLI::detail::trim_copy(raw);
      if (line.empty() || line[0] == '#' || line[0] == ';') continue;
      if (line[0] == '[')
        fail(n, "tables (" + line +
                    ") are not run config keys: set the options' long names "
                    "at the top level");
      size_t eq = line.find('=');
      if (eq == std::string::npos) fail(n, "expected NAME = VALUE");
      std::string key = CLI::detail::trim_copy(line.substr(0, eq));
      std::string value = CLI::detail::trim_copy(line.substr(eq + 1));
      if (key.empty()) fail(n, "expected NAME = VALUE");
      if (auto [it, fresh] = seen.emplace(key, n); !fresh)
        fail(n, key + " set again (first on line " + std::to_string(it->second) + ")");
      if (!value.empty() && (value[0] == '"' || value[0] == '\'')) {
        size_t end = closingQuote(value);
        if (end == std::string::npos) fail(n, key + ": a string without its closing quote");
        std::string rest = CLI::detail::trim_copy(value.substr(end + 1));
        if (!rest.empty() && rest[0] != '#') fail(n, key + ": '" + rest + "' after the string");
      } else if (!value.empty() && value[0] == '[' && value.back() != ']') {
        fail(n, key + ": an array without its closing ]");
      }
      const CLI::Option* o = app_->get_option_no_throw("--" + key);
      // The command line was parsed first: an option it set keeps its value.
      if (o && o->count() == 0) applied_.insert(key);
      if (o && o->get_expected_max() == 0 && value != "true" && value != "false")
        fail(n, key + ": a switch takes true or false, not " + value);
    }
  }
  const CLI::App* app_;
  mutable std::set<std::string> applied_;

 public:
  // The keys whose values came from the file (the command line did not set
  // them), once it has been read: exitParse names the file in their errors.
  const std::set<std::string>& applied() const { return applied_; }
};

inline void addConfigOption(CLI::App& app) {
  app.set_config("--config", "", "run config file (TOML or INI: option names without --)");
  app.config_formatter(std::make_shared<StrictConfig>(&app));
  app.allow_config_extras(CLI::config_extras_mode::error);
}

// app.exit(e) for a parse error, but an error in the run config names the
// config file (CLI11's own message does not).
inline int exitParse(CLI::App& app, const CLI::ParseError& e) {
  std::string file = app.get_config_ptr() && app.get_config_ptr()->count()
                         ? app.get_config_ptr()->as<std::string>()
                         : "";
  bool from_file = dynamic_cast<const CLI::ConfigError*>(&e) != nullptr;
  // A bad value the run config gave ("--width: Value abc not in range"):
  // CLI11 names the option, not where its value came from.
  if (auto cfg = std::dynamic_pointer_cast<StrictConfig>(app.get_config_formatter());
      cfg && !file.empty()) {
    const std::string what = e.what();
    for (const std::string& key : cfg->applied())
      if (what.find("--" + key + ":") != std::string::npos ||
          what.find("--" + key + " ") != std::string::npos)
        from_file = true;
  }
  if (from_file) {
    std::fprintf(stderr, "%s: %s: %s\n", app.get_name().c_str(), file.c_str(), e.what());
    return 1;
  }
  return app.exit(e);
}

}  // namespace dmmr
