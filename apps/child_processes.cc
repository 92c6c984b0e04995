#include "child_processes.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <thread>

#include "moslam/common/errors.h"

namespace moslam::cli {

pid_t SpawnSelf(const std::vector<std::string>& args, const std::filesystem::path& log) {
  std::vector<char*> argv;
  for (const std::string& s : args) argv.push_back(const_cast<char*>(s.c_str()));
  argv.push_back(nullptr);
  const std::string log_path = log.string();
  const pid_t pid = ::fork();
  if (pid < 0) throw Error("cannot start a child process: fork failed");
  if (pid == 0) {
    const int fd = ::open(log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0) {
      ::dup2(fd, 1);
      ::dup2(fd, 2);
      ::close(fd);
    }
    ::execv("/proc/self/exe", argv.data());
    ::_exit(127);
  }
  return pid;
}

std::map<int, int> WaitForChildren(const std::map<pid_t, int>& children,
                                   std::chrono::milliseconds timeout) {
  using Clock = std::chrono::steady_clock;
  const auto deadline = Clock::now() + timeout;
  std::map<int, int> exit_codes;
  while (exit_codes.size() < children.size()) {
    int status = 0;
    const pid_t pid = ::waitpid(-1, &status, WNOHANG);
    if (pid > 0 && children.count(pid)) {
      exit_codes[children.at(pid)] =
          WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      continue;
    }
    if (Clock::now() > deadline) {
      for (const auto& [p, id] : children) {
        if (!exit_codes.count(id)) ::kill(p, SIGKILL);
      }
      for (const auto& [p, id] : children) {
        if (!exit_codes.count(id)) {
          ::waitpid(p, &status, 0);
          exit_codes[id] = -1;
        }
      }
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return exit_codes;
}

}  // namespace moslam::cli
