// Cache budgets as the user gives them: "unlimited", or a byte count with an
// optional binary suffix (K, M, G, T; "KiB" and "KB" read the same), as on
// the command line (--gpu-budget, --ram-budget) and in run configs.
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <map>
#include <string>

#include "lru.h"

namespace dmmr {

struct CacheOptions {
  uint64_t gpu_budget = LruBudget::kUnlimited;  // per GL context
  uint64_t ram_budget = LruBudget::kUnlimited;  // per client process
  std::string ram_dir;                          // RAM-disk directory; empty: process memory
  bool prefetch = true;                         // clients: load ahead on the loader thread
  Eviction eviction = Eviction::FrameLru;
};

// Throws Error saying what is wrong with `text`.
uint64_t parseByteSize(const std::string& text);
std::string formatByteSize(uint64_t bytes);  // "unlimited", "12.5 MiB", ...

// --gpu-budget, --ram-budget, --ram-dir.
inline void addCacheOptions(CLI::App& app, CacheOptions& c) {
  auto budget = [&app](const char* name, uint64_t* out, const char* help) {
    app.add_option_function<std::string>(
           name, [out](const std::string& s) { *out = parseByteSize(s); }, help)
        ->check([](const std::string& s) {
          try {
            parseByteSize(s);
            return std::string();
          } catch (const std::exception& e) {
            return std::string(e.what());
          }
        });
  };
  budget("--gpu-budget", &c.gpu_budget,
         "GPU bytes for geometry and textures, per GL context (e.g. 512M; default unlimited)");
  budget("--ram-budget", &c.ram_budget,
         "host RAM bytes for geometry files, per client (e.g. 4G; default unlimited)");
  app.add_option("--ram-dir", c.ram_dir,
                 "keep the RAM level as files in this directory (a RAM disk, e.g. /dev/shm)");
  // Parsed as a name and checked by name, so that help and errors show the
  // names (the enum's one-byte values would print as control characters).
  app.add_option_function<std::string>(
         "--eviction",
         [&c](const std::string& v) {
           c.eviction = v == "lru" ? Eviction::Lru : Eviction::FrameLru;
         },
         "cache eviction: frame-lru (LRU, but MRU within a frame that overflows the budget) or "
         "lru (default frame-lru)")
      ->check(CLI::IsMember({"frame-lru", "lru"}));
  app.add_flag("!--no-prefetch", c.prefetch,
               "clients load geometry only when a stage draws it (for measuring prefetch)");
}

}  // namespace dmmr
