// A benchmark mode in which the GL stages of every client on one machine take
// turns (`dmmr-render --stage-turns FILE`): each stage holds an exclusive lock
// on one file while it works on a job, so no two stages run at once and a
// stage's wall time is its cost alone, free of contention for cores.
#pragma once

#include <string>

namespace dmmr {

class StageTurns {
 public:
  // Opens (creating it if needed) the lock file; throws Error naming it when
  // it cannot. Each StageTurns is its own open file description, so two of
  // them in one process exclude each other too (flock(2)).
  explicit StageTurns(const std::string& path);
  ~StageTurns();
  StageTurns(const StageTurns&) = delete;
  StageTurns& operator=(const StageTurns&) = delete;

  // Blocks until no other holder of the file's lock holds it, then holds it.
  void take();
  // Gives the lock up (no-op when not held).
  void give();

  // Holds the turn for a scope; `turns` may be null (no turns).
  class Hold {
   public:
    explicit Hold(StageTurns* turns) : turns_(turns) {
      if (turns_) turns_->take();
    }
    ~Hold() {
      if (turns_) turns_->give();
    }
    Hold(const Hold&) = delete;
    Hold& operator=(const Hold&) = delete;

   private:
    StageTurns* turns_;
  };

 private:
  std::string path_;
  int fd_ = -1;
  bool held_ = false;
};

}  // namespace dmmr
