// libFuzzer target for run configs (--config FILE): the renderers' options,
// read by CLI11 from TOML/INI text, with dmmr's own validators (byte sizes,
// ranges). Any input must give options or a CLI11 error, never a crash.
#include <CLI/CLI.hpp>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <sstream>
#include <string>

#include "budget.h"
#include "cli_options.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  CLI::App app{"fuzz"};
  dmmr::RunPaths paths;
  dmmr::ViewOptions view;
  dmmr::CacheOptions cache;
  dmmr::addRunOptions(app, paths, view);
  dmmr::addCacheOptions(app, cache);
  app.allow_config_extras(CLI::config_extras_mode::error);
  app.config_formatter(std::make_shared<dmmr::StrictConfig>(&app));  // as addConfigOption
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  try {
    app.parse_from_stream(in);
  } catch (const CLI::Error&) {
    return 0;
  }
  // What was accepted passed the validators.
  FUZZ_CHECK(view.width >= 1 && view.width <= 16384 && view.height >= 1 && view.height <= 16384);
  FUZZ_CHECK(view.fovy_deg >= 1.0 && view.fovy_deg <= 179.0);
  return 0;
}
