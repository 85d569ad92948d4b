#include "assimp_warnings.h"

#include <assimp/DefaultLogger.hpp>
#include <assimp/LogStream.hpp>

#include <mutex>

namespace probebake::job_internal {
namespace {

// The capture of this thread's import, or null: imports run on many threads at once, each with
// its own capture, while assimp has one global logger.
thread_local std::vector<std::string>* tCaptured = nullptr;

class ThreadCaptureStream final : public Assimp::LogStream {
 public:
  void write(const char* message) override {
    if (tCaptured != nullptr) tCaptured->emplace_back(message);
  }
};

void InstallLogger() {
  static std::once_flag once;
  std::call_once(once, [] {
    Assimp::Logger* logger = Assimp::DefaultLogger::create("", Assimp::Logger::NORMAL, 0);
    logger->attachStream(new ThreadCaptureStream,
                         Assimp::Logger::Warn | Assimp::Logger::Err);  // the logger owns it
  });
}

thread_local std::vector<std::string> tWarnings;

}  // namespace

AssimpWarningCapture::AssimpWarningCapture() {
  InstallLogger();
  tWarnings.clear();
  tCaptured = &tWarnings;
}

AssimpWarningCapture::~AssimpWarningCapture() {
  tCaptured = nullptr;
}

const std::vector<std::string>& AssimpWarningCapture::warnings() const {
  return tWarnings;
}

bool AssimpWarningCapture::Saw(const std::string& text) const {
  for (const std::string& w : tWarnings)
    if (w.find(text) != std::string::npos) return true;
  return false;
}

}  // namespace probebake::job_internal
