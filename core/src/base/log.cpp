#include "probebake/base/log.h"

#include <mutex>

#include <spdlog/sinks/stdout_color_sinks.h>

namespace probebake {
namespace {

struct LogState {
  std::mutex mutex;
  spdlog::sink_ptr sink = std::make_shared<spdlog::sinks::stderr_color_sink_mt>();
  spdlog::level::level_enum level = spdlog::level::info;
  std::string pattern = "[%Y-%m-%d %H:%M:%S.%e] [%n] [%^%l%$] %v";
};

LogState& State() {
  static LogState* state = new LogState;  // never destroyed: loggers may log during exit
  return *state;
}

}  // namespace

std::shared_ptr<spdlog::logger> Logger(const std::string& component) {
  LogState& state = State();
  std::lock_guard lock(state.mutex);
  if (auto existing = spdlog::get(component)) return existing;
  auto logger = std::make_shared<spdlog::logger>(component, state.sink);
  logger->set_level(state.level);
  logger->set_pattern(state.pattern);
  spdlog::register_logger(logger);
  return logger;
}

void SetLogLevel(spdlog::level::level_enum level) {
  LogState& state = State();
  std::lock_guard lock(state.mutex);
  state.level = level;
  spdlog::apply_all([&](const std::shared_ptr<spdlog::logger>& l) { l->set_level(level); });
}

void SetLogPattern(const std::string& pattern) {
  LogState& state = State();
  std::lock_guard lock(state.mutex);
  state.pattern = pattern;
  spdlog::apply_all([&](const std::shared_ptr<spdlog::logger>& l) { l->set_pattern(pattern); });
}

}  // namespace probebake
