#include "progress.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace drape::app {

bool stderr_is_terminal() { return isatty(STDERR_FILENO) != 0; }

namespace {

std::string fixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

// "42 s", "3 min 05 s", "1 h 02 min": what a person reads at a glance.
std::string duration_text(double s) {
  if (s < 60) return fixed(s, s < 10 ? 1 : 0) + " s";
  const long total = std::lround(s);
  char buf[64];
  if (total < 3600)
    std::snprintf(buf, sizeof buf, "%ld min %02ld s", total / 60, total % 60);
  else
    std::snprintf(buf, sizeof buf, "%ld h %02ld min", total / 3600, total % 3600 / 60);
  return buf;
}

}  // namespace

std::string progress_text(std::string_view what, std::int64_t done, std::int64_t total, std::int64_t first,
                          double seconds, bool bar) {
  std::string line;
  const double fraction = total > 0 ? std::clamp(double(done) / double(total), 0.0, 1.0) : 1.0;
  if (bar) {
    constexpr int width = 30;
    const int filled = int(fraction * width);
    line.push_back('[');
    line.append(filled, '#').append(width - filled, '.').append("] ");
  }
  // appends, not operator+ chains: GCC 12 warns falsely (-Wrestrict) on those
  line.append(what).append(" ").append(std::to_string(done)).append("/").append(std::to_string(total));
  line.append(" (").append(std::to_string(int(fraction * 100))).append("%)");
  const std::int64_t counted = done - first;
  if (counted > 0 && seconds > 0) {
    const double rate = double(counted) / seconds;
    line.append(", ").append(fixed(rate, rate < 10 ? 2 : 1)).append(" ").append(what).append("s/s, ");
    line.append(duration_text(double(total - done) / rate)).append(" left");
  } else {
    line.append(", ? s left");
  }
  return line;
}

Progress::Progress(std::ostream& out, std::string what, std::int64_t total, bool terminal, std::int64_t first,
                   std::chrono::steady_clock::duration every)
    : out_(out), what_(std::move(what)), total_(total), first_(first), next_line_(first), terminal_(terminal),
      every_(every) {}

void Progress::update(std::int64_t done, std::string_view detail) {
  const std::lock_guard lock(mutex_);
  const auto now = std::chrono::steady_clock::now();
  const double seconds = std::chrono::duration<double>(now - start_).count();
  if (terminal_) {
    // Redraw at most 10 times a second; always for the last item.
    if (done < total_ && drawn_ && now - last_draw_ < std::chrono::milliseconds(100)) return;
    last_draw_ = now;
    drawn_ = true;
    // \033[K clears what a longer previous line left behind.
    out_ << "\r" << progress_text(what_, done, total_, first_, seconds, true) << "\033[K" << std::flush;
    return;
  }
  // Plain lines: one per tenth of the work, one when `every` passed since the last, and the last.
  const std::int64_t step = std::max<std::int64_t>(1, (total_ - first_) / 10);
  if (done < next_line_ + step && done < total_ && !(done > next_line_ && now - last_draw_ >= every_)) return;
  next_line_ = done;
  last_draw_ = now;
  out_ << "drape: " << progress_text(what_, done, total_, first_, seconds, false);
  if (!detail.empty()) out_ << ", " << detail;
  out_ << '\n';
}

void Progress::finish() {
  const std::lock_guard lock(mutex_);
  if (terminal_ && drawn_) out_ << '\n';
  drawn_ = false;
}

}  // namespace drape::app
