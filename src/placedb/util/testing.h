// Helpers for tests only (header-only, GoogleTest): a scratch directory and a
// check that a call throws a given exception type whose message contains
// given parts.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <opencv2/core.hpp>
#include <opencv2/core/utility.hpp>
#include <string>
#include <utility>
#include <vector>

#include "placedb/util/error.h"

namespace placedb {
namespace testing_util {

// A fresh directory under the system temp dir, removed with its contents.
// Named after the running test (or "suite" when made in a SetUpTestSuite).
class TempDir {
 public:
  TempDir() {
    const ::testing::TestInfo* info = ::testing::UnitTest::GetInstance()->current_test_info();
    const std::string test =
        info ? std::string(info->test_suite_name()) + "_" + info->name() : std::string("suite");
    path_ =
        std::filesystem::temp_directory_path() / ("placedb_test_" + std::to_string(getpid()) + "_" +
                                                  test + "_" + std::to_string(counter_++));
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  // Absolute path of `relative` inside the directory.
  std::string Path(const std::string& relative = "") const { return (path_ / relative).string(); }

  // Writes `content` to `relative` (parent folders created) and returns its path.
  std::string Write(const std::string& relative, const std::string& content) const {
    const std::filesystem::path file = path_ / relative;
    std::filesystem::create_directories(file.parent_path());
    std::ofstream(file, std::ios::binary) << content;
    return file.string();
  }

 private:
  std::filesystem::path path_;
  static inline int counter_ = 0;  // several directories in one test
};

#if defined(__has_feature)
#define PLACEDB_TESTING_HAS_FEATURE(x) __has_feature(x)
#else
#define PLACEDB_TESTING_HAS_FEATURE(x) 0
#endif
// True in a ThreadSanitizer build, where a test that forks a multi-threaded
// process cannot run (TSan does not support threads after such a fork).
#if defined(__SANITIZE_THREAD__) || PLACEDB_TESTING_HAS_FEATURE(thread_sanitizer)
constexpr bool kThreadSanitizer = true;
#else
constexpr bool kThreadSanitizer = false;
#endif
// True in an AddressSanitizer build (whose shadow memory takes more address
// space than a test's limit on it allows).
#if defined(__SANITIZE_ADDRESS__) || PLACEDB_TESTING_HAS_FEATURE(address_sanitizer)
constexpr bool kAddressSanitizer = true;
#else
constexpr bool kAddressSanitizer = false;
#endif

// Under ThreadSanitizer, OpenCV runs its functions on the calling thread:
// its TBB worker threads are not instrumented, so TSan cannot see their
// synchronisation and would report races inside OpenCV. placedb's own
// threads are still checked. (Every test binary includes this header. One
// thread, not 0: with TBB, getNumThreads() reports 2 after 0, and code that
// saves and restores the count would bring the workers back.)
[[maybe_unused]] static const bool kOpenCvSequentialUnderTsan = [] {
  if (kThreadSanitizer) cv::setNumThreads(1);
  return true;
}();

// Runs `fn`; succeeds when it throws `Exception` whose what() contains every
// one of `parts`.
template <typename Exception, typename Fn>
::testing::AssertionResult ThrowsWith(Fn&& fn, std::initializer_list<std::string> parts) {
  try {
    fn();
  } catch (const Exception& e) {
    const std::string message = e.what();
    for (const std::string& part : parts) {
      if (message.find(part) == std::string::npos) {
        return ::testing::AssertionFailure()
               << "message '" << message << "' lacks '" << part << "'";
      }
    }
    return ::testing::AssertionSuccess() << message;
  } catch (const std::exception& e) {
    return ::testing::AssertionFailure() << "wrong exception type: " << e.what();
  }
  return ::testing::AssertionFailure() << "nothing thrown";
}

// Every field of two keypoint lists is equal (determinism, round trips);
// any containers of cv::KeyPoint with size() and operator[].
template <typename A, typename B>
void ExpectSameKeypoints(const A& a, const B& b) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].pt, b[i].pt) << "keypoint " << i;
    EXPECT_EQ(a[i].size, b[i].size) << "keypoint " << i;
    EXPECT_EQ(a[i].angle, b[i].angle) << "keypoint " << i;
    EXPECT_EQ(a[i].response, b[i].response) << "keypoint " << i;
    EXPECT_EQ(a[i].octave, b[i].octave) << "keypoint " << i;
    EXPECT_EQ(a[i].class_id, b[i].class_id) << "keypoint " << i;
  }
}

#ifdef PLACEDB_DATA_DIR
// Path of image n (1..84) of the shipped RTAB-Map loop sequence.
inline std::string RtabmapImage(int n) {
  char name[32];
  std::snprintf(name, sizeof(name), "/%03d.jpg", n);
  return std::string(PLACEDB_DATA_DIR "/rtabmap_loop/images") + name;
}
#endif

// The same with one phrase.
template <typename Exception, typename Fn>
::testing::AssertionResult ThrowsWith(Fn&& fn, const std::string& phrase) {
  return ThrowsWith<Exception>(std::forward<Fn>(fn), {phrase});
}

// Whether a SIMD kernel left the upper halves of the vector registers in
// use. XINUSE (XGETBV with ECX = 1): bit 2 says the upper halves of
// ymm0-15 may be non-zero, bit 6 those of zmm0-15. A kernel that returns
// with them dirty makes the caller's SSE code merge upper halves on every
// instruction (measured: the whole-keyframe match 1.5x slower); each ends
// with vzeroupper. DirtyUpperStateKnown() is false where XGETBV(1) is
// missing (the tests then skip).
#if defined(__x86_64__) && defined(__linux__)
inline bool DirtyUpperStateKnown() {
  unsigned eax, ebx, ecx, edx;
  __asm__("cpuid" : "=a"(eax), "=b"(ebx), "=c"(ecx), "=d"(edx) : "a"(1), "c"(0));
  if (!(ecx & (1u << 27))) return false;  // OSXSAVE
  __asm__("cpuid" : "=a"(eax), "=b"(ebx), "=c"(ecx), "=d"(edx) : "a"(0xd), "c"(1));
  return (eax & (1u << 2)) != 0;  // XGETBV with ECX = 1
}
__attribute__((noinline)) inline bool DirtyUpperState() {
  unsigned lo, hi;
  __asm__ volatile("xgetbv" : "=a"(lo), "=d"(hi) : "c"(1));
  return ((static_cast<uint64_t>(hi) << 32 | lo) & ((1u << 2) | (1u << 6))) != 0;
}
#else
inline bool DirtyUpperStateKnown() { return false; }
inline bool DirtyUpperState() { return false; }
#endif

}  // namespace testing_util
}  // namespace placedb
