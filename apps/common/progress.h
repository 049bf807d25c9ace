// Progress of a long command (`drape run` frames, `drape sweep` runs): on a terminal one line
// redrawn in place — a bar, the count, items per second and the time left — and otherwise
// (a pipe, a log file) a plain line every tenth of the work, at least every half minute
// (a long run's log shows it alive), and at the end, so logs stay readable. Safe to call
// from several threads (sweep runs finish on worker threads).
#pragma once

#include <chrono>
#include <cstdint>
#include <mutex>
#include <ostream>
#include <string>
#include <string_view>

namespace drape::app {

// True when standard error is a terminal (where the bar is drawn).
bool stderr_is_terminal();

// One progress line without the prefix: "frame 30/300 (10%), 45.2 frames/s, 6.0 s left", the
// rate and time left from `seconds` spent on `done − first` items (first: items done before,
// e.g. by a resumed run); "…, ? s left" until one item is done. With `bar`, a 30-wide
// "[#####.....] " comes first.
std::string progress_text(std::string_view what, std::int64_t done, std::int64_t total, std::int64_t first,
                          double seconds, bool bar);

class Progress {
 public:
  // `what` names one item ("frame", "run"); plurals add an "s". Items 0..first are done already.
  // `every`: the longest a pipe waits for a plain line while items get done.
  Progress(std::ostream& out, std::string what, std::int64_t total, bool terminal, std::int64_t first = 0,
           std::chrono::steady_clock::duration every = std::chrono::seconds(30));
  // `done` items are complete; `detail` (e.g. "t = 0.5 s") is appended to a plain line.
  void update(std::int64_t done, std::string_view detail = {});
  // Ends the redrawn line (call before any other message once the bar was drawn).
  void finish();

 private:
  std::mutex mutex_;
  std::ostream& out_;
  std::string what_;
  std::int64_t total_, first_, next_line_;
  bool terminal_, drawn_ = false;
  std::chrono::steady_clock::duration every_;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now(), last_draw_ = start_;
};

}  // namespace drape::app
