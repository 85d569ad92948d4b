// Logging: one spdlog logger per component ("core", "bake", "job", "volume", "server", "client",
// ...), created on first use and sharing one sink, so every line says where it came from.
#pragma once

#include <memory>
#include <string>

#include <spdlog/spdlog.h>

namespace probebake {

// The logger of `component`; thread safe; never null.
std::shared_ptr<spdlog::logger> Logger(const std::string& component);

// Sets the level of every probebake logger, existing and future ("trace" ... "off").
void SetLogLevel(spdlog::level::level_enum level);

// Sends every probebake logger to stderr (the default) with the given pattern.
void SetLogPattern(const std::string& pattern);

}  // namespace probebake
