// A frame: one image of a sequence with its id, timestamp and, when known, its
// ground-truth pose. Produced by the dataset readers, consumed by build/query.
#pragma once

#include <cstdint>
#include <functional>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "placedb/util/error.h"
#include "placedb/util/pose.h"
#include "placedb/util/option_table.h"

namespace placedb {

// Image files are decoded only after their header says how many pixels they
// hold: a PNG of under 1 MB can declare 30000 x 30000 pixels (2.7 GB of BGR).
// The default bound, 40 megapixels, is 120 MB of BGR: above any camera frame
// placedb is meant for (8K video is 33 megapixels; the sample data is at most
// 800 x 640), and small enough that a few frames decoded at once on every
// core stay far from a machine's memory.
constexpr int64_t kDefaultMaxImagePixels = 40000000;

struct ImageReadOptions {
  // Largest image decoded, in pixels (width x height as the file's header
  // declares them, checked before anything is decoded); also the largest
  // simulated camera (Frame::resize_to). Default 40 000 000; range
  // [1, 2^30] (2^30 is OpenCV's own limit).
  int64_t max_pixels = kDefaultMaxImagePixels;

  // The options' names, defaults, ranges and help (util/option_table.h).
  static const OptionTable<ImageReadOptions>& Table();
  std::string Check() const;
};

// What an image file's first bytes say: its format and size. Formats read:
// PNG, JPEG (baseline, progressive, lossless), BMP, PNM (P1 to P6), PAM
// (P7), PFM (PF, Pf) and WebP (VP8, VP8L, VP8X), found by the same signatures
// OpenCV's decoders check. Any other format (TIFF, OpenEXR, JPEG 2000,
// Radiance HDR, Sun raster, ...) is not read: those decoders size their
// buffers from fields a header check here would have to trust as well.
struct ImageHeader {
  std::string format;  // "png", "jpeg", "bmp", "pnm", "pam", "pfm", "webp"
  int64_t width = 0, height = 0;
};
// The header of the encoded image `data`; std::nullopt, and why in `*error`,
// for an unknown format or a header cut short or impossible (a side of 0 or
// above 2^31 - 1).
std::optional<ImageHeader> ReadImageHeader(const uint8_t* data, size_t size, std::string* error);

// An image decoded as 8-bit BGR (cv::IMREAD_COLOR, as cv::imread would),
// with what went wrong: `image` is empty when `error` is set. `too_large` is
// set (and nothing was decoded) when the header declares more than
// max_pixels.
struct DecodedImage {
  cv::Mat image;
  std::string error;
  bool too_large = false;
  // What kind of error `error` is: kNotFound (no file at the path), kIo (the
  // file cannot be read), else kInvalidArgument (not an image we decode, or
  // too large).
  ErrorKind kind = ErrorKind::kInvalidArgument;
  // XXH3-64 of the bytes decoded (TryReadImageFile: the file's), as
  // SourceHash gives it; 0 when nothing was read.
  uint64_t bytes_hash = 0;
};
// Throws the error of `d` (d.error set) as its kind, with `message`
// (d.error when empty).
[[noreturn]] void ThrowImageError(const DecodedImage& d, const std::string& message = "");
// Decodes encoded image bytes (a file's, a message's). `what` names them in
// `error`. Never throws for bad bytes.
DecodedImage DecodeImage(const uint8_t* data, size_t size, const ImageReadOptions& options,
                         const std::string& what);
// Reads the regular file `path` once (at most 12 bytes per allowed pixel
// plus 16 MiB: larger is refused before reading) and decodes it as
// DecodeImage does. A path that is not a regular file (a FIFO, a device, a
// folder) is an error, never a wait.
DecodedImage TryReadImageFile(const std::string& path, const ImageReadOptions& options);
// The same, throwing the error ("cannot read image PATH: ...", or "image PATH
// is W x H pixels, more than ..."): NotFound, IoError or InvalidArgument.
cv::Mat ReadImageFile(const std::string& path, const ImageReadOptions& options);

struct Frame {
  int id = 0;               // 1-based position in the source listing (folder, list file, rgb.txt)
  double timestamp = -1.0;  // seconds; -1 when unknown
  std::string image_path;   // absolute or as given, usable with cv::imread; or a
                            // description of where `load` reads from
  // When set, reads the image instead of cv::imread(image_path): frames from
  // a bag. Must be callable from several threads at once.
  std::function<cv::Mat()> load;
  std::optional<Pose> pose;  // ground-truth camera pose (camera-to-world), when known
  // When not empty, the image is brought to this size as it is read: a
  // smaller camera, simulated (area interpolation down, bilinear up).
  cv::Size resize_to;
  // How image_path is decoded (its pixel bound).
  ImageReadOptions read;
};

// Reads a frame's image as 8-bit BGR (resized to frame.resize_to when set),
// through TryReadImageFile; an empty Mat when it cannot be read or decoded.
// InvalidArgument when the file declares more than read.max_pixels pixels,
// or resize_to is larger than that: the bound is never skipped over
// silently.
cv::Mat LoadFrameImage(const Frame& frame);

// The same, also giving the frame's source hash (SourceHash): of the file's
// bytes as read for decoding (one read), or of the decoded image for a
// frame with `load` (a bag). *source_hash is 0 when the image is empty.
cv::Mat LoadFrameImage(const Frame& frame, uint64_t* source_hash);

// What a keyframe records of its source's content (Keyframe::source_hash):
// XXH3-64 of an image file's bytes, never 0 (a hash of 0 becomes 1: 0 means
// "not recorded"). For frames without a file, SourceHashOfPixels hashes the
// decoded image (its size, type and pixel rows).
uint64_t SourceHash(const void* data, size_t size);
uint64_t SourceHashOfPixels(const cv::Mat& image);

// For a frame LoadFrameImage could not read: throws NotFound when its image
// file does not exist, else InvalidArgument ("cannot read image PATH (frame
// N<context>)"; `context` e.g. "; `strict`").
[[noreturn]] void ThrowUnreadableFrame(const Frame& frame, const std::string& context = "");

// Frames first..last of a listing (1-based positions; last 0: to the end).
// InvalidArgument, naming `what` ("TUM frame", "bag frame"), for
// first < 1, last < 0 or a range that selects nothing.
std::vector<Frame> SelectFrameRange(std::vector<Frame> frames, int first, int last,
                                    const std::string& what);

// How a range is written in source descriptions (manifests, reports):
// " [first..last]", " [first..]", or "" for the whole listing.
std::string FrameRangeSuffix(int first, int last);

// Sets resize_to on every frame.
void ResizeFramesTo(std::vector<Frame>* frames, cv::Size size);
// Sets the image read options of every frame (checked).
void SetImageReadOptions(std::vector<Frame>* frames, const ImageReadOptions& options);

}  // namespace placedb
