// How the command-line programs (placedb, the ROS nodes) report an error: one
// line on stderr and an exit code that tells a script what kind of failure
// it was (sysexits.h where one fits).
//
//   0   success
//   1   the input: a bad argument or option value (InvalidArgument), a
//       missing file or database (NotFound), a damaged one (CorruptDatabase),
//       a command line that does not parse
//   70  a bug in placedb (InternalError, or an exception placedb does not
//       know: EX_SOFTWARE); the line asks for a report
//   74  the system failed a read or a write (IoError: EX_IOERR)
#pragma once

#include <exception>
#include <string>

#include "placedb/util/error.h"

namespace placedb {
namespace cli {

constexpr int kExitOk = 0;
constexpr int kExitInput = 1;
constexpr int kExitSoftware = 70;  // EX_SOFTWARE
constexpr int kExitIo = 74;        // EX_IOERR

// The exit code of `e`'s kind.
int ExitCode(const Error& e);

// The text of the error line after "<program>: error: ": the message with
// option names written as flags (`top_k` -> --top-k), escaped for a terminal
// (one line, whatever bytes the message quotes from files). An InternalError
// says it is a bug to report. `verbose` appends where it was thrown
// (" [storage/database.cc:123]").
std::string FormatForCommandLine(const Error& e, bool verbose);

// For main(), inside a catch block: prints "<program>: error: <text>" for the
// exception being handled and returns the exit code. placedb::Error as
// above; std::filesystem errors are I/O (74); anything else (std::bad_alloc,
// cv::Exception, ...) is 70.
int ReportCurrentException(const std::string& program, bool verbose);

}  // namespace cli
}  // namespace placedb
