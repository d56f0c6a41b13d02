#include "placedb/cli/errors.h"

#include <cstdio>
#include <filesystem>
#include <new>
#include <opencv2/core.hpp>

#include "placedb/cli/options.h"
#include "placedb/util/file_io.h"

namespace placedb {
namespace cli {
namespace {

constexpr char kBug[] = "internal error (a bug in placedb; please report it): ";

}  // namespace

int ExitCode(const Error& e) {
  switch (e.kind()) {
    case ErrorKind::kInvalidArgument:
    case ErrorKind::kNotFound:
    case ErrorKind::kCorruptDatabase:
      return kExitInput;
    case ErrorKind::kIo:
      return kExitIo;
    case ErrorKind::kInternal:
      return kExitSoftware;
  }
  return kExitSoftware;
}

std::string FormatForCommandLine(const Error& e, bool verbose) {
  std::string text = FormatOptionNames(e.message(), FlagOf);
  const bool bug = e.kind() == ErrorKind::kInternal;
  if (bug) text = kBug + text;
  // A bug report needs the line even without --verbose.
  if ((verbose || bug) && !e.where().empty()) text += " [" + e.where() + "]";
  return EscapeForTerminal(text);
}

int ReportCurrentException(const std::string& program, bool verbose) {
  std::string text;
  int code = kExitSoftware;
  try {
    throw;
  } catch (const Error& e) {
    text = FormatForCommandLine(e, verbose);
    code = ExitCode(e);
  } catch (const std::filesystem::filesystem_error& e) {
    // A std::filesystem call that failed: the system's, like IoError.
    text = EscapeForTerminal(e.what());
    code = kExitIo;
  } catch (const std::bad_alloc&) {
    text = "out of memory";
  } catch (const cv::Exception& e) {
    // cv::Exception's what() is several lines with OpenCV's source path: its
    // short text and function name are enough.
    text = EscapeForTerminal(kBug + ("OpenCV: " + e.err) +
                             (e.func.empty() ? "" : " (in " + e.func + ")"));
  } catch (const std::exception& e) {
    text = EscapeForTerminal(kBug + std::string(e.what()));
  } catch (...) {
    text = std::string(kBug) + "an exception of an unknown type";
  }
  std::fprintf(stderr, "%s: error: %s\n", program.c_str(), text.c_str());
  return code;
}

}  // namespace cli
}  // namespace placedb
