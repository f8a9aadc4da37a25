// Helpers shared by dmmr's tests: temporary directories, tool paths, and the
// real models beside the checkout.
#pragma once

#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "error.h"

namespace dmmr::test {

// The message of the dmmr::Error that `f` throws, or "" when it throws none.
template <typename F>
std::string errorOf(F&& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

// A fresh directory under the system temp dir, removed when destroyed.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::string& path() const { return path_; }
  std::string operator/(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
};

// ../shared/models beside the source tree, or "" when it is absent.
std::string sharedModelsDir();
// build/bin/NAME.
std::string tool(const std::string& name);
// "mpirun -np N" with the flags this machine needs (--oversubscribe,
// --bind-to none so that a client's GL threads are not pinned to one core,
// and --allow-run-as-root when running as root), exporting the sanitizers'
// *SAN_OPTIONS to the ranks when they are set.
std::string mpirun(int np);
// `text` with every character that is not a letter or digit dropped: a
// test-name and file-name part made from command-line options.
std::string slug(const std::string& text);
// Runs a shell command; returns its exit status (-1 when it did not exit).
int run(const std::string& command);
// Runs a command and returns its stdout+stderr; *status gets the exit status.
std::string runCapture(const std::string& command, int* status);

// A numeric CSV (the stats files) as one map per row, column name to value.
// Throws Error naming the file and line when a row's cells do not match the
// header.
std::vector<std::map<std::string, double>> readCsv(const std::string& path);

// Flips the bits of the byte at `offset`, so the file changes whatever the
// byte held.
void flipByte(const std::string& file, long offset);

}  // namespace dmmr::test
