// Interrupted commands leave no temporary files: see rayscan/base/interrupt.hpp.
#include "rayscan/base/interrupt.hpp"

#include <dirent.h>
#include <fcntl.h>
#include <limits.h>
#include <pthread.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <iterator>
#include <string>

namespace rayscan {

namespace {

// A slot's state. A slot is claimed (free -> filling), its path copied, then published (file or
// folder). The handler takes a published slot (-> taken) before reading its path, and a mark
// frees only a slot it still finds published, so the handler never reads a path being rewritten.
enum SlotState : int { kFree = 0, kFilling = 1, kFile = 2, kFolder = 3, kTaken = 4 };

constexpr int kSlots = 128;

struct Slot {
  std::atomic<int> state{kFree};
  char path[PATH_MAX];
};

static_assert(std::atomic<int>::is_always_lock_free && std::atomic<bool>::is_always_lock_free,
              "the handler may only use lock-free atomics");

// Zero-initialised storage: the pages of unused slots are never touched.
Slot g_slots[kSlots];
std::atomic<bool> g_marking{false};  // marks are recorded (a handler is or may be installed)
std::atomic<bool> g_deferred{false};
std::atomic<int> g_pending{0};
std::atomic<bool> g_cleaning{false};

constexpr int kSignals[] = {SIGINT, SIGTERM, SIGHUP};

/// Empties the folder `path` (its entries; a sub-folder only if empty) and removes it. Only
/// async-signal-safe calls: the entries are read by getdents64(2), not opendir(3), which allocates.
void remove_folder(const char* path) {
  const int fd = ::open(path, O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
  if (fd >= 0) {
    alignas(dirent64) char buf[4096];
    // Entries removed while the folder is read may move others past the read position: read it
    // again until a pass removes nothing (bounded, in case an entry cannot be removed).
    for (int pass = 0; pass < 16; ++pass) {
      bool removed = false;
      ::lseek(fd, 0, SEEK_SET);
      for (ssize_t n; (n = ::getdents64(fd, buf, sizeof buf)) > 0;) {
        for (ssize_t off = 0; off < n;) {
          const auto* d = reinterpret_cast<const dirent64*>(buf + off);
          off += d->d_reclen;
          const char* name = d->d_name;
          if (std::strcmp(name, ".") == 0 || std::strcmp(name, "..") == 0) continue;
          if (::unlinkat(fd, name, 0) == 0 || ::unlinkat(fd, name, AT_REMOVEDIR) == 0) removed = true;
        }
      }
      if (!removed) break;
    }
    ::close(fd);
  }
  ::rmdir(path);
}

extern "C" void on_interrupt(int sig) {
  const int saved_errno = errno;
  if (g_deferred.load()) {
    int none = 0;
    if (g_pending.compare_exchange_strong(none, sig)) {  // the first signal: the job stops itself
      errno = saved_errno;
      return;
    }
  }
  // Another thread got a signal too and is removing the marks: it ends the process.
  if (g_cleaning.exchange(true))
    for (;;) ::pause();
  remove_marked_paths();
  // End by the signal itself, so that the parent sees how the process ended.
  struct sigaction dfl {};
  dfl.sa_handler = SIG_DFL;
  sigemptyset(&dfl.sa_mask);
  ::sigaction(sig, &dfl, nullptr);
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, sig);
  ::pthread_sigmask(SIG_UNBLOCK, &set, nullptr);
  ::raise(sig);
  ::_exit(128 + sig);  // not reached: the default action of the three signals ends the process
}

/// The action that runs on_interrupt.
struct sigaction handler_action() {
  struct sigaction sa {};
  sa.sa_handler = on_interrupt;
  sigemptyset(&sa.sa_mask);
  for (const int s : kSignals) sigaddset(&sa.sa_mask, s);  // one handler at a time per thread
  sa.sa_flags = SA_RESTART;  // a deferred signal does not cut reads and writes short
  return sa;
}

// The InterruptCleanup objects alive and the signals they took (those at SIG_DFL when the first
// was made), under a pthread mutex that fork() holds (pthread_atfork), so a child finds it free.
pthread_mutex_t g_cleanup_mutex = PTHREAD_MUTEX_INITIALIZER;
int g_cleanups = 0;
bool g_taken[std::size(kSignals)] = {};
pthread_once_t g_atfork_once = PTHREAD_ONCE_INIT;

/// Gives each signal taken its default action back, unless the host set another one meanwhile.
/// Under g_cleanup_mutex.
void give_back_signals() {
  for (std::size_t i = 0; i < std::size(kSignals); ++i) {
    if (!g_taken[i]) continue;
    g_taken[i] = false;
    struct sigaction now {};
    if (::sigaction(kSignals[i], nullptr, &now) != 0 || (now.sa_flags & SA_SIGINFO) != 0 ||
        now.sa_handler != on_interrupt)
      continue;
    struct sigaction dfl {};
    dfl.sa_handler = SIG_DFL;
    sigemptyset(&dfl.sa_mask);
    ::sigaction(kSignals[i], &dfl, nullptr);
  }
}

void lock_for_fork() { ::pthread_mutex_lock(&g_cleanup_mutex); }
void unlock_after_fork() { ::pthread_mutex_unlock(&g_cleanup_mutex); }

/// In a child forked while the parent's threads write (os.fork, multiprocessing): the writes and
/// their InterruptCleanup objects stay in the parent, so the child gets the default actions back
/// and forgets the marks, which name the parent's temporaries. (Registered only by processes that
/// make an InterruptCleanup, never by the `rayscan` program, whose forking thread holds no mark.)
void reset_in_child() {
  if (g_cleanups > 0) give_back_signals();
  g_cleanups = 0;
  for (Slot& s : g_slots) {
    const int state = s.state.load();
    if (state == kFile || state == kFolder) s.state.store(kFree);
  }
  ::pthread_mutex_unlock(&g_cleanup_mutex);
}

void register_fork_handlers() { ::pthread_atfork(lock_for_fork, unlock_after_fork, reset_in_child); }

}  // namespace

void remove_marked_paths() noexcept {
  // Each slot is taken once (published -> taken), so a signal arriving meanwhile, or a second
  // caller, removes only what this one has not.
  for (Slot& s : g_slots) {
    int state = s.state.load();
    if ((state == kFile || state == kFolder) && s.state.compare_exchange_strong(state, kTaken)) {
      if (state == kFolder)
        remove_folder(s.path);
      else
        ::unlink(s.path);
    }
  }
}

RemoveOnInterrupt::RemoveOnInterrupt(const std::filesystem::path& path, Kind kind) noexcept {
  if (!g_marking.load()) return;
  const std::string& p = path.native();
  if (p.empty() || p.size() >= PATH_MAX) return;
  for (int i = 0; i < kSlots; ++i) {
    int expected = kFree;
    if (g_slots[i].state.compare_exchange_strong(expected, kFilling)) {
      std::memcpy(g_slots[i].path, p.c_str(), p.size() + 1);
      g_slots[i].state.store(kind == Kind::folder ? kFolder : kFile);
      slot_ = i;
      return;
    }
  }
}

RemoveOnInterrupt::RemoveOnInterrupt(RemoveOnInterrupt&& other) noexcept : slot_(other.slot_) { other.slot_ = -1; }

RemoveOnInterrupt& RemoveOnInterrupt::operator=(RemoveOnInterrupt&& other) noexcept {
  if (this != &other) {
    release();
    slot_ = other.slot_;
    other.slot_ = -1;
  }
  return *this;
}

RemoveOnInterrupt::~RemoveOnInterrupt() { release(); }

void RemoveOnInterrupt::release() noexcept {
  if (slot_ < 0) return;
  std::atomic<int>& state = g_slots[slot_].state;
  int s = state.load();
  // Taken by the handler: the process is ending; the slot is left to it.
  while ((s == kFile || s == kFolder) && !state.compare_exchange_weak(s, kFree)) {
  }
  slot_ = -1;
}

void install_interrupt_handler() {
  g_marking.store(true);
  const struct sigaction sa = handler_action();
  for (const int s : kSignals) {
    struct sigaction old {};
    if (::sigaction(s, nullptr, &old) == 0 && old.sa_handler == SIG_IGN) continue;
    ::sigaction(s, &sa, nullptr);
  }
}

InterruptCleanup::InterruptCleanup() noexcept {
  ::pthread_once(&g_atfork_once, register_fork_handlers);
  ::pthread_mutex_lock(&g_cleanup_mutex);
  if (g_cleanups++ == 0) {
    g_marking.store(true);
    const struct sigaction sa = handler_action();
    for (std::size_t i = 0; i < std::size(kSignals); ++i) {
      struct sigaction old {};
      // Only the default action, which would end the process anyway: the host's handler (a
      // Python-level one included) or an ignored signal stays as it is.
      if (::sigaction(kSignals[i], nullptr, &old) != 0 || (old.sa_flags & SA_SIGINFO) != 0 ||
          old.sa_handler != SIG_DFL)
        continue;
      g_taken[i] = ::sigaction(kSignals[i], &sa, nullptr) == 0;
    }
  }
  ::pthread_mutex_unlock(&g_cleanup_mutex);
}

InterruptCleanup::~InterruptCleanup() {
  ::pthread_mutex_lock(&g_cleanup_mutex);
  if (--g_cleanups == 0) give_back_signals();
  ::pthread_mutex_unlock(&g_cleanup_mutex);
}

void defer_interrupts() noexcept { g_deferred.store(true); }

int pending_interrupt() noexcept { return g_pending.load(); }

}  // namespace rayscan
