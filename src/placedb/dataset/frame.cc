#include "placedb/dataset/frame.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <png.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "placedb/util/check.h"
#include "placedb/util/checksum.h"
#include "placedb/util/file_io.h"
#include "placedb/util/options.h"

namespace placedb {

namespace {

constexpr int64_t kMaxSide = 0x7fffffff;

uint32_t Be16(const uint8_t* p) { return (uint32_t{p[0]} << 8) | p[1]; }
uint32_t Be32(const uint8_t* p) {
  return (uint32_t{p[0]} << 24) | (uint32_t{p[1]} << 16) | (uint32_t{p[2]} << 8) | p[3];
}
uint32_t Le16(const uint8_t* p) { return uint32_t{p[0]} | (uint32_t{p[1]} << 8); }
uint32_t Le24(const uint8_t* p) { return Le16(p) | (uint32_t{p[2]} << 16); }
uint32_t Le32(const uint8_t* p) { return Le24(p) | (uint32_t{p[3]} << 24); }

bool StartsWith(const uint8_t* data, size_t size, const char* magic, size_t n) {
  return size >= n && std::memcmp(data, magic, n) == 0;
}

// JPEG: the segments from SOI up to the first frame header (SOFn).
std::optional<ImageHeader> JpegHeader(const uint8_t* d, size_t n, std::string* error) {
  size_t i = 2;
  while (true) {
    if (i >= n || d[i] != 0xFF) break;
    while (i < n && d[i] == 0xFF) ++i;  // fill bytes
    if (i >= n) break;
    const uint8_t marker = d[i++];
    if (marker == 0xD8 || marker == 0x01 || (marker >= 0xD0 && marker <= 0xD7)) continue;
    if (marker == 0xD9 || marker == 0xDA) {
      *error = "JPEG: no frame header before the image data";
      return std::nullopt;
    }
    if (n - i < 2) break;
    const uint32_t length = Be16(d + i);
    if (length < 2 || length > n - i) break;
    const bool sof =
        marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC;
    if (sof) {
      if (length < 8) break;
      ImageHeader h{"jpeg", Be16(d + i + 5), Be16(d + i + 3)};
      return h;
    }
    i += length;
  }
  *error = "JPEG: the header is cut short or malformed";
  return std::nullopt;
}

// PNM / PFM: whitespace-separated decimal fields after the 2-byte magic, '#'
// comments to the end of a line.
bool NextNumber(const uint8_t* d, size_t n, size_t* i, int64_t* value) {
  while (*i < n) {
    if (d[*i] == '#') {
      while (*i < n && d[*i] != '\n' && d[*i] != '\r') ++*i;
    } else if (std::isspace(d[*i])) {
      ++*i;
    } else {
      break;
    }
  }
  int64_t v = 0;
  size_t digits = 0;
  while (*i < n && d[*i] >= '0' && d[*i] <= '9') {
    if (++digits > 10) return false;
    v = v * 10 + (d[*i] - '0');
    ++*i;
  }
  if (digits == 0) return false;
  *value = v;
  return true;
}

// PAM: "TOKEN value" lines up to ENDHDR.
std::optional<ImageHeader> PamHeader(const uint8_t* d, size_t n, std::string* error) {
  ImageHeader h{"pam", 0, 0};
  size_t i = 2;
  while (i < n) {
    while (i < n && std::isspace(d[i])) ++i;
    if (i < n && d[i] == '#') {
      while (i < n && d[i] != '\n') ++i;
      continue;
    }
    const size_t begin = i;
    while (i < n && !std::isspace(d[i])) ++i;
    const std::string token(reinterpret_cast<const char*>(d + begin), i - begin);
    if (token == "ENDHDR") return h;
    if (token == "WIDTH" || token == "HEIGHT") {
      int64_t v = 0;
      if (!NextNumber(d, n, &i, &v)) break;
      (token == "WIDTH" ? h.width : h.height) = v;
    }
    if (token.empty()) break;
  }
  *error = "PAM: the header is cut short or malformed";
  return std::nullopt;
}

}  // namespace

std::optional<ImageHeader> ReadImageHeader(const uint8_t* d, size_t n, std::string* error) {
  std::optional<ImageHeader> h;
  std::string why;
  if (StartsWith(d, n, "\x89PNG\r\n\x1a\n", 8)) {
    if (n >= 24 && std::memcmp(d + 12, "IHDR", 4) == 0) {
      h = ImageHeader{"png", Be32(d + 16), Be32(d + 20)};
    } else {
      why = "PNG: no IHDR chunk where it must be";
    }
  } else if (StartsWith(d, n, "\xFF\xD8\xFF", 3)) {
    h = JpegHeader(d, n, &why);
  } else if (StartsWith(d, n, "BM", 2)) {
    if (n >= 18 && Le32(d + 14) == 12 && n >= 22) {
      h = ImageHeader{"bmp", Le16(d + 18), Le16(d + 20)};
    } else if (n >= 26 && Le32(d + 14) >= 16) {
      const int32_t w = static_cast<int32_t>(Le32(d + 18)), ht = static_cast<int32_t>(Le32(d + 22));
      h = ImageHeader{"bmp", w, ht == INT32_MIN ? int64_t{1} << 31 : std::abs(int64_t{ht})};
    } else {
      why = "BMP: the header is cut short or malformed";
    }
  } else if (n >= 2 && d[0] == 'P' &&
             ((d[1] >= '1' && d[1] <= '6') || d[1] == 'F' || d[1] == 'f')) {
    size_t i = 2;
    int64_t w = 0, ht = 0;
    if (NextNumber(d, n, &i, &w) && NextNumber(d, n, &i, &ht)) {
      h = ImageHeader{d[1] == 'F' || d[1] == 'f' ? "pfm" : "pnm", w, ht};
    } else {
      why = "PNM: the header is cut short or malformed";
    }
  } else if (StartsWith(d, n, "P7", 2)) {
    h = PamHeader(d, n, &why);
  } else if (n >= 12 && std::memcmp(d, "RIFF", 4) == 0 && std::memcmp(d + 8, "WEBP", 4) == 0) {
    if (n >= 30 && std::memcmp(d + 12, "VP8 ", 4) == 0 && d[23] == 0x9d && d[24] == 0x01 &&
        d[25] == 0x2a) {
      h = ImageHeader{"webp", Le16(d + 26) & 0x3fff, Le16(d + 28) & 0x3fff};
    } else if (n >= 25 && std::memcmp(d + 12, "VP8L", 4) == 0 && d[20] == 0x2f) {
      const uint32_t bits = Le32(d + 21);
      h = ImageHeader{"webp", (bits & 0x3fff) + 1, ((bits >> 14) & 0x3fff) + 1};
    } else if (n >= 30 && std::memcmp(d + 12, "VP8X", 4) == 0) {
      h = ImageHeader{"webp", int64_t{Le24(d + 24)} + 1, int64_t{Le24(d + 27)} + 1};
    } else {
      why = "WebP: the header is cut short or malformed";
    }
  } else {
    why = n == 0 ? "the file is empty"
                 : "not an image format placedb reads (PNG, JPEG, BMP, PNM/PAM/PFM, WebP)";
  }
  if (h && (h->width < 1 || h->height < 1 || h->width > kMaxSide || h->height > kMaxSide)) {
    why = fmt::format("{}: the header declares an impossible size {} x {}", h->format, h->width,
                      h->height);
    h.reset();
  }
  if (!h && error != nullptr) *error = why;
  return h;
}

namespace {
std::string TooLarge(const std::string& what, const ImageHeader& h, int64_t max_pixels) {
  return fmt::format(
      "{} is {} x {} pixels ({:.1f} megapixels), more than the {} pixels allowed (raise the bound "
      "with `max_image_pixels`)",
      what, h.width, h.height, static_cast<double>(h.width) * static_cast<double>(h.height) / 1e6,
      max_pixels);
}
// PNG through libpng with placedb's own error and warning handlers: OpenCV's
// decoder leaves libpng's defaults, which print "libpng error: ..." (and
// warnings) on stderr before placedb's own line. The transforms are
// OpenCV 4.6's for IMREAD_COLOR (its PngDecoder::readData), so the pixels
// are the same (png_decode_test holds the two equal on every kind of PNG).
struct PngInput {
  const uint8_t* data;
  size_t size;
  size_t pos;
};
struct PngErrors {
  char message[160];
};

void PngRead(png_structp png, png_bytep out, png_size_t n) {
  auto* in = static_cast<PngInput*>(png_get_io_ptr(png));
  if (n > in->size - in->pos) png_error(png, "the data is cut short");
  std::memcpy(out, in->data + in->pos, n);
  in->pos += n;
}
void PngError(png_structp png, png_const_charp message) {
  auto* errors = static_cast<PngErrors*>(png_get_error_ptr(png));
  std::snprintf(errors->message, sizeof(errors->message), "%s", message);
  png_longjmp(png, 1);
}
void PngWarning(png_structp, png_const_charp) {}

// The PNG in `data` as BGR 8-bit, or empty with `*error` set. Every C++
// object lives from before setjmp (a longjmp skips no destructor).
cv::Mat DecodePng(const uint8_t* data, size_t size, std::string* error) {
  PngInput input{data, size, 0};
  PngErrors errors{};
  cv::Mat image;
  std::vector<png_bytep> rows;
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &errors, PngError, PngWarning);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  png_infop end = png ? png_create_info_struct(png) : nullptr;
  if (png == nullptr || info == nullptr || end == nullptr) {
    png_destroy_read_struct(&png, &info, &end);
    *error = "out of memory";
    return cv::Mat();
  }
  if (setjmp(png_jmpbuf(png)) != 0) {
    png_destroy_read_struct(&png, &info, &end);
    *error = errors.message;
    image.release();
    return cv::Mat();
  }
  png_set_read_fn(png, &input, PngRead);
  png_read_info(png, info);
  png_uint_32 width = 0, height = 0;
  int bit_depth = 0, color_type = 0;
  png_get_IHDR(png, info, &width, &height, &bit_depth, &color_type, nullptr, nullptr, nullptr);
  if (bit_depth == 16) png_set_strip_16(png);
  png_set_strip_alpha(png);
  if (color_type == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
  if ((color_type & PNG_COLOR_MASK_COLOR) == 0 && bit_depth < 8)
    png_set_expand_gray_1_2_4_to_8(png);
  if (color_type & PNG_COLOR_MASK_COLOR) {
    png_set_bgr(png);
  } else {
    png_set_gray_to_rgb(png);
  }
  png_set_interlace_handling(png);
  png_read_update_info(png, info);
  image.create(static_cast<int>(height), static_cast<int>(width), CV_8UC3);
  if (png_get_rowbytes(png, info) != image.step[0]) png_error(png, "unexpected row size");
  rows.resize(height);
  for (png_uint_32 y = 0; y < height; ++y) rows[y] = image.ptr<png_byte>(static_cast<int>(y));
  png_read_image(png, rows.data());
  png_read_end(png, end);
  png_destroy_read_struct(&png, &info, &end);
  return image;
}

}  // namespace

DecodedImage DecodeImage(const uint8_t* data, size_t size, const ImageReadOptions& options,
                         const std::string& what) {
  PLACEDB_CHECK_OPTIONS(options);
  DecodedImage out;
  std::string why;
  const std::optional<ImageHeader> h = ReadImageHeader(data, size, &why);
  if (!h) {
    out.error = "cannot read " + what + ": " + why;
    return out;
  }
  if (h->width * h->height > options.max_pixels) {
    out.error = TooLarge(what, *h, options.max_pixels);
    out.too_large = true;
    return out;
  }
  std::string decoder_error;
  if (h->format == "png") {
    out.image = DecodePng(data, size, &decoder_error);
  } else {
    try {
      const cv::Mat encoded(1, static_cast<int>(std::min<size_t>(size, INT32_MAX)), CV_8U,
                            const_cast<uint8_t*>(data));
      out.image = cv::imdecode(encoded, cv::IMREAD_COLOR);
    } catch (const cv::Exception& e) {
      out.image.release();
    }
  }
  if (out.image.empty()) {
    out.error = "cannot read " + what + ": the " + h->format + " data cannot be decoded" +
                (decoder_error.empty() ? "" : " (" + decoder_error + ")");
  } else if (static_cast<int64_t>(out.image.cols) * out.image.rows > options.max_pixels) {
    // The decoder read another size than the header check (it cannot, for
    // the formats read; a guard all the same).
    out.image.release();
    out.error = "cannot read " + what + ": decoded to another size than its header declares";
  }
  return out;
}

DecodedImage TryReadImageFile(const std::string& path, const ImageReadOptions& options) {
  PLACEDB_CHECK_OPTIONS(options);
  DecodedImage out;
  const std::string what = "image " + path;
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK | O_NOCTTY);
  if (fd < 0) {
    out.kind = errno == ENOENT || errno == ENOTDIR ? ErrorKind::kNotFound : ErrorKind::kIo;
    out.error = "cannot read " + what + ": " + std::strerror(errno);
    return out;
  }
  std::string bytes;
  struct stat st;
  const uint64_t max_bytes = static_cast<uint64_t>(options.max_pixels) * 12 + (16u << 20);
  if (::fstat(fd, &st) != 0) {
    out.kind = ErrorKind::kIo;
    out.error = "cannot read " + what + ": " + std::strerror(errno);
  } else if (!S_ISREG(st.st_mode)) {
    out.error = "cannot read " + what + ": not a regular file";
  } else if (static_cast<uint64_t>(st.st_size) > max_bytes) {
    out.error = fmt::format(
        "cannot read {}: the file has {} bytes, more than an image of the {} "
        "pixels allowed can need",
        what, st.st_size, options.max_pixels);
    out.too_large = true;
  } else {
    bytes.resize(static_cast<size_t>(st.st_size));
    size_t done = 0;
    while (done < bytes.size()) {
      const ssize_t got = ::read(fd, &bytes[done], bytes.size() - done);
      if (got < 0 && errno == EINTR) continue;
      if (got < 0) {
        out.kind = ErrorKind::kIo;
        out.error = "cannot read " + what + ": " + std::strerror(errno);
      }
      if (got <= 0) break;
      done += static_cast<size_t>(got);
    }
    bytes.resize(done);  // a file that shrank meanwhile: what was read
  }
  ::close(fd);
  if (!out.error.empty()) return out;
  DecodedImage d =
      DecodeImage(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size(), options, what);
  d.bytes_hash = SourceHash(bytes.data(), bytes.size());
  return d;
}

uint64_t SourceHash(const void* data, size_t size) {
  const uint64_t h = Checksum64(data, size);
  return h == 0 ? 1 : h;
}

uint64_t SourceHashOfPixels(const cv::Mat& image) {
  if (image.empty()) return 0;
  Checksum64Stream sum;
  const int32_t shape[4] = {image.rows, image.cols, image.type(), 0};
  sum.Update(shape, sizeof(shape));
  const size_t row_bytes = static_cast<size_t>(image.cols) * image.elemSize();
  for (int r = 0; r < image.rows; ++r) sum.Update(image.ptr(r), row_bytes);
  const uint64_t h = sum.Digest();
  return h == 0 ? 1 : h;
}

void ThrowImageError(const DecodedImage& d, const std::string& message) {
  const std::string& text = message.empty() ? d.error : message;
  switch (d.kind) {
    case ErrorKind::kNotFound:
      PLACEDB_THROW_NOT_FOUND(text);
    case ErrorKind::kIo:
      PLACEDB_THROW_IO(text);
    default:
      PLACEDB_THROW_INVALID(text);
  }
}

cv::Mat ReadImageFile(const std::string& path, const ImageReadOptions& options) {
  DecodedImage d = TryReadImageFile(path, options);
  if (!d.error.empty()) ThrowImageError(d);
  return std::move(d.image);
}

cv::Mat LoadFrameImage(const Frame& frame) { return LoadFrameImage(frame, nullptr); }

cv::Mat LoadFrameImage(const Frame& frame, uint64_t* source_hash) {
  if (source_hash) *source_hash = 0;
  PLACEDB_CHECK_OPTIONS(frame.read);
  if (static_cast<int64_t>(frame.resize_to.width) * frame.resize_to.height >
      frame.read.max_pixels) {
    PLACEDB_THROW_INVALID("frame ", frame.id, ": the simulated camera size ", frame.resize_to.width,
                          "x", frame.resize_to.height, " is more than the ", frame.read.max_pixels,
                          " pixels allowed (`max_image_pixels`)");
  }
  cv::Mat image;
  if (frame.load) {
    image = frame.load();
    if (source_hash) *source_hash = SourceHashOfPixels(image);
  } else {
    DecodedImage d = TryReadImageFile(frame.image_path, frame.read);
    if (d.too_large) PLACEDB_THROW_INVALID("frame ", frame.id, ": ", d.error);
    image = std::move(d.image);
    if (source_hash && !image.empty()) *source_hash = d.bytes_hash;
  }
  if (image.empty() || frame.resize_to.empty() || image.size() == frame.resize_to) return image;
  const bool down = frame.resize_to.area() < image.size().area();
  cv::Mat resized;
  cv::resize(image, resized, frame.resize_to, 0, 0, down ? cv::INTER_AREA : cv::INTER_LINEAR);
  return resized;
}

void ThrowUnreadableFrame(const Frame& frame, const std::string& context) {
  // Frame 0 is no listing's: a single file (read_image).
  const std::string which =
      frame.id == 0 && context.empty() ? "" : " (frame " + std::to_string(frame.id) + context + ")";
  struct stat st;
  if (!frame.load && ::stat(frame.image_path.c_str(), &st) != 0 &&
      (errno == ENOENT || errno == ENOTDIR)) {
    PLACEDB_THROW_NOT_FOUND("image ", frame.image_path, " does not exist", which);
  }
  PLACEDB_THROW_INVALID("cannot read image ", frame.image_path, which);
}

std::vector<Frame> SelectFrameRange(std::vector<Frame> frames, int first, int last,
                                    const std::string& what) {
  if (first < 1) PLACEDB_THROW_INVALID("`first` must be >= 1 (got ", first, ")");
  if (last < 0) PLACEDB_THROW_INVALID("`last` must be >= 0 (0: to the end; got ", last, ")");
  const size_t begin = static_cast<size_t>(first - 1);
  const size_t end = last == 0 ? frames.size() : std::min(frames.size(), static_cast<size_t>(last));
  if (begin >= frames.size() || begin >= end) {
    PLACEDB_THROW_INVALID("`first` and `last` select no ", what, " (", frames.size(), " listed)");
  }
  return std::vector<Frame>(frames.begin() + static_cast<ptrdiff_t>(begin),
                            frames.begin() + static_cast<ptrdiff_t>(end));
}

std::string FrameRangeSuffix(int first, int last) {
  if (first == 1 && last == 0) return "";
  return last == 0 ? fmt::format(" [{}..]", first) : fmt::format(" [{}..{}]", first, last);
}

void ResizeFramesTo(std::vector<Frame>* frames, cv::Size size) {
  for (Frame& f : *frames) f.resize_to = size;
}

void SetImageReadOptions(std::vector<Frame>* frames, const ImageReadOptions& options) {
  PLACEDB_CHECK_OPTIONS(options);
  for (Frame& f : *frames) f.read = options;
}

}  // namespace placedb
