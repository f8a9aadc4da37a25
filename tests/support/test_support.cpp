#include "test_support.h"
#include <cctype>

#include <fstream>
#include <sstream>

#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <stdexcept>

namespace dmmr::test {

TempDir::TempDir() {
  static std::atomic<int> counter{0};
  std::string base = std::filesystem::temp_directory_path().string();
  path_ = base + "/dmmr-test-" + std::to_string(::getpid()) + "-" + std::to_string(counter++);
  std::filesystem::remove_all(path_);
  std::filesystem::create_directories(path_);
}

TempDir::~TempDir() {
  std::error_code ec;
  if (!std::getenv("DMMR_KEEP_TEST_FILES")) std::filesystem::remove_all(path_, ec);
}

std::string sharedModelsDir() {
  std::string dir = std::string(DMMR_SOURCE_DIR) + "/../shared/models";
  return std::filesystem::is_directory(dir) ? dir : "";
}

std::string tool(const std::string& name) {
  return std::string(DMMR_BIN_DIR) + "/" + name;
}

std::string mpiSessionBase() {
  // One parent per test process, removed when it exits; a fresh child per
  // launch. Open MPI 4.1 creates <TMPDIR>/ompi.<host>.<uid> with a racy
  // mkdir, so two mpirun jobs starting at once under one TMPDIR can fail
  // with "A call to mkdir was unable to create the desired directory ...
  // File exists" (open-mpi/ompi#8510; seen in CI with ctest -j2).
  static const std::string parent = [] {
    std::string dir =
        std::filesystem::temp_directory_path().string() + "/dmmr-mpi-" + std::to_string(::getpid());
    std::filesystem::create_directories(dir);
    std::atexit([] {
      std::error_code ec;
      std::filesystem::remove_all(std::filesystem::temp_directory_path().string() + "/dmmr-mpi-" +
                                      std::to_string(::getpid()),
                                  ec);
    });
    return dir;
  }();
  std::string tmpl = parent + "/XXXXXX";
  if (!::mkdtemp(tmpl.data()))
    throw std::runtime_error("test_support: cannot create a directory under " + parent);
  return tmpl;
}

std::string mpirun(int np) {
  std::string cmd = "env TMPDIR=" + mpiSessionBase() +
                    " mpirun --oversubscribe --bind-to none -np " + std::to_string(np);
  if (::geteuid() == 0) cmd += " --allow-run-as-root";
  // The sanitizer builds' settings (suppressions, halt_on_error, leak
  // checks: tests/sanitizers/) go to every rank, wherever it runs.
  for (const char* var : {"ASAN_OPTIONS", "LSAN_OPTIONS", "UBSAN_OPTIONS", "TSAN_OPTIONS"})
    if (std::getenv(var)) cmd += std::string(" -x ") + var;
  return cmd;
}

std::string slug(const std::string& text) {
  std::string out;
  for (char c : text)
    if (std::isalnum(static_cast<unsigned char>(c))) out += c;
  return out;
}

int run(const std::string& command) {
  int s = std::system(command.c_str());
  return WIFEXITED(s) ? WEXITSTATUS(s) : -1;
}

namespace {
// mpirun's report of a rank that exited "improperly" with no PID, with no
// message from dmmr at all: seen twice on the development machine in full
// suite runs (many mpirun jobs starting at once), never reproduced alone;
// taken as a launch failure and tried once more (runCapture), loudly.
bool launchFailure(const std::string& command, int status, const std::string& out) {
  return status != 0 && command.find("mpirun") != std::string::npos &&
         out.find("with PID 0 on node") != std::string::npos &&
         out.find("dmmr-") == std::string::npos;
}
}  // namespace

std::string runCapture(const std::string& command, int* status, double* seconds) {
  std::string out = runCaptureOnce(command, status, seconds);
  if (!launchFailure(command, *status, out)) return out;
  std::fprintf(stderr,
               "test_support: mpirun reported a rank that never ran properly; once more:\n%s\n",
               out.c_str());
  return runCaptureOnce(command, status, seconds);
}

std::string runCaptureOnce(const std::string& command, int* status, double* seconds) {
  auto t0 = std::chrono::steady_clock::now();
  std::string out;
  FILE* p = ::popen((command + " 2>&1").c_str(), "r");
  if (!p) {
    *status = -1;
    return out;
  }
  std::array<char, 4096> buf;
  size_t n;
  while ((n = std::fread(buf.data(), 1, buf.size(), p)) > 0) out.append(buf.data(), n);
  int s = ::pclose(p);
  *status = WIFEXITED(s) ? WEXITSTATUS(s) : -1;
  if (seconds)
    *seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

std::vector<CsvRow> readCsv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw Error(fileError(path, "cannot open"));
  auto split = [](const std::string& line) {
    std::vector<std::string> cells;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) cells.push_back(cell);
    return cells;
  };
  std::vector<CsvRow> rows;
  std::string line;
  if (!std::getline(in, line)) throw Error(fileError(path, "no header line"));
  std::vector<std::string> header = split(line);
  for (long number = 2; std::getline(in, line); ++number) {
    std::vector<std::string> cells = split(line);
    if (cells.size() != header.size())
      throw Error(fileError(path, number,
                            "has " + std::to_string(cells.size()) + " cells, the header " +
                                std::to_string(header.size())));
    CsvRow row(path);
    for (size_t i = 0; i < cells.size(); ++i) {
      char* end = nullptr;
      double value = std::strtod(cells[i].c_str(), &end);
      if (cells[i].empty() || *end != '\0')
        throw Error(fileError(
            path, number, "column \"" + header[i] + "\": \"" + cells[i] + "\" is not a number"));
      row.entry(header[i]) = value;
    }
    rows.push_back(std::move(row));
  }
  return rows;
}

void flipByte(const std::string& file, long offset) {
  std::fstream f(file, std::ios::in | std::ios::out | std::ios::binary);
  f.seekg(offset);
  char c = char(f.get() ^ 0x5a);
  f.seekp(offset);
  f.put(c);
}

}  // namespace dmmr::test
