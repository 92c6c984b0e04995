// process_stats: runs one command as a fresh process and prints its wall time (fork to reaping)
// and peak resident memory (ru_maxrss from wait4) as one JSON line on stderr; the command's own
// stdout passes through. Forked from this small process, so the peak a child inherits before
// exec is a few MB (forking from Python would count the interpreter's). For
// bench/whole_process.py; usable on its own:
//   process_stats moslam solve smallGrid3D.g2o
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: process_stats COMMAND [ARG ...]\n");
    return 2;
  }
  const auto start = std::chrono::steady_clock::now();
  const pid_t pid = fork();
  if (pid < 0) {
    std::fprintf(stderr, "process_stats: fork: %s\n", std::strerror(errno));
    return 2;
  }
  if (pid == 0) {
    execvp(argv[1], argv + 1);
    std::fprintf(stderr, "process_stats: cannot run %s: %s\n", argv[1], std::strerror(errno));
    _exit(127);
  }
  int status = 0;
  struct rusage usage {};
  while (wait4(pid, &status, 0, &usage) < 0) {
    if (errno != EINTR) {
      std::fprintf(stderr, "process_stats: wait4: %s\n", std::strerror(errno));
      return 2;
    }
  }
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const int code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  std::fprintf(stderr, "{\"wall_seconds\": %.6f, \"peak_kb\": %ld, \"exit\": %d}\n", wall,
               usage.ru_maxrss, code);
  return code;
}
