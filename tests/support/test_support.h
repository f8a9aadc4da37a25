// Helpers shared by dmmr's tests: temporary directories, tool paths, and the
// real models beside the checkout.
#pragma once

#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>
#include <utility>
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
// *SAN_OPTIONS to the ranks when they are set. Each call's job gets its own
// Open MPI session directory (TMPDIR from mpiSessionBase), so that jobs
// started at once do not race to create the same one.
std::string mpirun(int np);
// A fresh directory, removed when the test process exits, for one mpirun
// job's session files.
std::string mpiSessionBase();
// `text` with every character that is not a letter or digit dropped: a
// test-name and file-name part made from command-line options.
std::string slug(const std::string& text);
// Runs a shell command; returns its exit status (-1 when it did not exit).
int run(const std::string& command);
// Runs a command and returns its stdout+stderr; *status gets the exit status.
// With `seconds`, also the command's wall time (tests that a failure ends
// the run promptly).
std::string runCapture(const std::string& command, int* status, double* seconds = nullptr);
// The same without the retry: runCapture runs an mpirun command once more
// when mpirun reports a rank that never ran properly (a rank "with PID 0"
// exiting improperly, no message from dmmr), a launch failure seen rarely
// when many mpirun jobs start at once.
std::string runCaptureOnce(const std::string& command, int* status, double* seconds = nullptr);

// Values by column name, read strictly: reading a column that is not there
// throws Error naming the file and the column, so a renamed column fails its
// test instead of reading as 0 (as std::map's operator[] would).
template <typename V>
class Columns {
 public:
  explicit Columns(std::string file) : file_(std::move(file)) {}
  const V& operator[](const std::string& name) const { return at(name); }
  const V& at(const std::string& name) const {
    auto it = values_.find(name);
    if (it == values_.end()) missing(name);
    return it->second;
  }
  bool contains(const std::string& name) const { return values_.count(name) != 0; }
  // For building: the value of `name`, value-initialised when new.
  V& entry(const std::string& name) { return values_[name]; }
  auto begin() const { return values_.begin(); }
  auto end() const { return values_.end(); }
  size_t size() const { return values_.size(); }
  const std::string& file() const { return file_; }

 private:
  [[noreturn]] void missing(const std::string& name) const {
    std::string have;
    for (const auto& [column, value] : values_) have += (have.empty() ? "" : ", ") + column;
    throw Error(fileError(file_, "no column \"" + name + "\" (columns: " + have + ")"));
  }
  std::string file_;
  std::map<std::string, V> values_;
};

using CsvRow = Columns<double>;

// A numeric CSV (the stats files), one row per line after the header. Throws
// Error naming the file (and line) when it cannot be read, a row's cells do
// not match the header, or a cell is not a number.
std::vector<CsvRow> readCsv(const std::string& path);

// Flips the bits of the byte at `offset`, so the file changes whatever the
// byte held.
void flipByte(const std::string& file, long offset);

}  // namespace dmmr::test
