#include "placedb/dataset/image_folder.h"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <stdexcept>
#include <vector>

#include "placedb/dataset/frame.h"
#include "placedb/util/testing.h"

namespace placedb {
namespace {

namespace fs = std::filesystem;
using testing_util::TempDir;
using testing_util::ThrowsWith;
using testing_util::RtabmapImage;

const std::string kData = PLACEDB_DATA_DIR;

std::string FileName(const Frame& frame) { return fs::path(frame.image_path).filename().string(); }

TEST(ImageFolderTest, RtabmapLoopHas84SortedImages) {
  const std::string dir = kData + "/rtabmap_loop/images";
  const std::vector<Frame> frames = ListImageFolder(dir);
  ASSERT_EQ(frames.size(), 84u);
  for (size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(frames[i].id, static_cast<int>(i + 1));
    char name[16];
    std::snprintf(name, sizeof(name), "%03d.jpg", static_cast<int>(i + 1));
    EXPECT_EQ(FileName(frames[i]), name);
    EXPECT_EQ(frames[i].timestamp, -1.0);
    EXPECT_FALSE(frames[i].pose.has_value());
  }
  const cv::Mat image = cv::imread(frames[0].image_path);
  ASSERT_FALSE(image.empty());
  EXPECT_EQ(image.cols, 512);
  EXPECT_EQ(image.rows, 384);
}

TEST(ImageFolderTest, RangeKeepsIds) {
  const std::string dir = kData + "/rtabmap_loop/images";
  const std::vector<Frame> queries = ListImageFolder(dir, 41, 84);
  ASSERT_EQ(queries.size(), 44u);
  for (size_t i = 0; i < queries.size(); ++i) EXPECT_EQ(queries[i].id, static_cast<int>(41 + i));
  EXPECT_EQ(FileName(queries.front()), "041.jpg");
  EXPECT_EQ(FileName(queries.back()), "084.jpg");

  const std::vector<Frame> database = ListImageFolder(dir, 1, 40);
  ASSERT_EQ(database.size(), 40u);
  EXPECT_EQ(database.back().id, 40);
  EXPECT_EQ(FileName(database.back()), "040.jpg");

  EXPECT_EQ(ListImageFolder(dir, 41).size(), 44u);  // last = 0: to the end
  const std::vector<Frame> one = ListImageFolder(dir, 84, 84);
  ASSERT_EQ(one.size(), 1u);
  EXPECT_EQ(one[0].id, 84);
  const std::vector<Frame> clamped = ListImageFolder(dir, 80, 100);  // last clamped, warning
  ASSERT_EQ(clamped.size(), 5u);
  EXPECT_EQ(clamped.back().id, 84);
}

TEST(ImageFolderTest, DeskLoopHasTenPngs) {
  const std::vector<Frame> frames = ListImageFolder(kData + "/tum_fr2_desk_loop/rgb");
  ASSERT_EQ(frames.size(), 10u);
  EXPECT_EQ(FileName(frames[0]), "01.png");
  EXPECT_EQ(FileName(frames[9]), "10.png");
  EXPECT_EQ(frames[9].id, 10);
  const cv::Mat image = cv::imread(frames[9].image_path);
  ASSERT_FALSE(image.empty());
  EXPECT_EQ(image.cols, 640);
  EXPECT_EQ(image.rows, 480);
}

TEST(ImageFolderTest, FiltersExtensionsCaseInsensitivelyAndSortsByName) {
  TempDir tmp;
  for (const char* name : {"b.PNG", "a.jpg", "e.JpEg", "f.tiff", "g.webp", "notes.txt",
                           ".hidden.jpg", "noext", "sub/d.jpg"}) {
    tmp.Write(name, "x");
  }
  fs::create_directories(tmp.Path("dir.png"));  // a directory with an image extension
  const std::vector<Frame> frames = ListImageFolder(tmp.Path());
  ASSERT_EQ(frames.size(), 5u);
  EXPECT_EQ(FileName(frames[0]), "a.jpg");
  EXPECT_EQ(FileName(frames[1]), "b.PNG");
  EXPECT_EQ(FileName(frames[2]), "e.JpEg");
  EXPECT_EQ(FileName(frames[3]), "f.tiff");
  EXPECT_EQ(FileName(frames[4]), "g.webp");
  EXPECT_EQ(frames[0].image_path, tmp.Path("a.jpg"));
}

TEST(ImageFolderTest, FolderErrorsNameTheDir) {
  TempDir tmp;
  const std::string missing = tmp.Path("missing");
  EXPECT_TRUE(ThrowsWith<NotFound>([&] { ListImageFolder(missing); }, {missing}));

  tmp.Write("empty/readme.txt", "no images here");
  const std::string empty = tmp.Path("empty");
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { ListImageFolder(empty); }, {empty, "no images"}));

  const std::string dir = kData + "/tum_fr2_desk_loop/rgb";
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { ListImageFolder(dir, 5, 3); },
                                          {dir, "first (5) is after last (3)"}));
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { ListImageFolder(dir, 11); },
                                          {dir, "beyond the 10 images"}));
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { ListImageFolder(dir, 0); }, {dir, "first"}));
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { ListImageFolder(dir, 1, -1); }, {dir}));
}

TEST(ImageFolderTest, ImageListWithRelativePathsAndComments) {
  TempDir tmp;
  tmp.Write("img/x.png", "x");
  tmp.Write("lists/y.jpg", "y");
  const std::string desk03 = kData + "/tum_fr2_desk_loop/rgb/03.png";
  const std::string list = tmp.Write("lists/list.txt",
                                     "# images of the test\n"
                                     "\n"
                                     "../img/x.png\r\n"
                                     "   # an indented comment\n"
                                     "  y.jpg  \n" +
                                         desk03 + "\n");
  const std::vector<Frame> frames = ReadImageList(list);
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[0].id, 1);
  EXPECT_EQ(frames[1].id, 2);
  EXPECT_EQ(frames[2].id, 3);
  EXPECT_TRUE(fs::equivalent(frames[0].image_path, tmp.Path("img/x.png")));
  EXPECT_EQ(frames[1].image_path, tmp.Path("lists/y.jpg"));
  EXPECT_EQ(frames[2].image_path, desk03);  // absolute entries are kept as they are
  EXPECT_FALSE(cv::imread(frames[2].image_path).empty());

  const std::vector<Frame> tail = ReadImageList(list, 2);
  ASSERT_EQ(tail.size(), 2u);
  EXPECT_EQ(tail[0].id, 2);
  EXPECT_EQ(tail[0].image_path, tmp.Path("lists/y.jpg"));
}

TEST(ImageFolderTest, ImageListErrors) {
  TempDir tmp;
  tmp.Write("a.png", "x");
  const std::string list = tmp.Write("list.txt", "# header\na.png\nmissing.png\n");
  // A missing image is kept (ids are list positions); the build skips it.
  const std::vector<Frame> frames = ReadImageList(list);
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[1].id, 2);
  EXPECT_NE(frames[1].image_path.find("missing.png"), std::string::npos);
  const std::string only_comments = tmp.Write("comments.txt", "# nothing\n\n");
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { ReadImageList(only_comments); },
                                          {only_comments, "no images"}));
  const std::string good = tmp.Write("good.txt", "a.png\n");
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { ReadImageList(good, 2); }, {good}));
  EXPECT_TRUE(ThrowsWith<NotFound>([&] { ReadImageList(tmp.Path("nope.txt")); }, {"nope.txt"}));
}

TEST(ImageFolderTest, ReadImagesDispatches) {
  EXPECT_EQ(ReadImages(kData + "/tum_fr2_desk_loop/rgb", 2, 4).size(), 3u);
  TempDir tmp;
  const std::string list = tmp.Write("list.txt", kData + "/rtabmap_loop/images/084.jpg\n");
  const std::vector<Frame> frames = ReadImages(list);
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_EQ(FileName(frames[0]), "084.jpg");
  EXPECT_TRUE(ThrowsWith<NotFound>([&] { ReadImages(tmp.Path("none")); }, {tmp.Path("none")}));
}


// ---- bounded image reading (issue 17: decompression bombs) -------------------

std::string Be32(uint32_t v) {
  return {static_cast<char>(v >> 24), static_cast<char>(v >> 16), static_cast<char>(v >> 8),
          static_cast<char>(v)};
}
std::string Le16(uint32_t v) { return {static_cast<char>(v), static_cast<char>(v >> 8)}; }
std::string Le32(uint32_t v) { return Le16(v & 0xffff) + Le16(v >> 16); }

// The first bytes of a PNG that declares width x height (no image data: a
// reader that trusts the header would allocate before finding that out).
std::string PngHeader(uint32_t width, uint32_t height) {
  return std::string("\x89PNG\r\n\x1a\n", 8) + Be32(13) + "IHDR" + Be32(width) + Be32(height) +
         std::string("\x08\x02\x00\x00\x00", 5) + Be32(0);
}

std::optional<ImageHeader> Header(const std::string& bytes, std::string* error = nullptr) {
  std::string ignored;
  return ReadImageHeader(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size(),
                         error ? error : &ignored);
}

TEST(ImageReadTest, HeadersOfEveryFormatGiveTheDecodedSize) {
  cv::Mat image(23, 37, CV_8UC3);
  cv::randu(image, 0, 255);
  int formats = 0;
  for (const std::string ext : {".png", ".jpg", ".bmp", ".ppm", ".pgm", ".pbm", ".pam", ".webp"}) {
    std::vector<uint8_t> encoded;
    try {
      if (!cv::imencode(ext, image, encoded)) continue;
    } catch (const cv::Exception&) {
      continue;  // no encoder in this OpenCV
    }
    ++formats;
    std::string error;
    const auto h = ReadImageHeader(encoded.data(), encoded.size(), &error);
    ASSERT_TRUE(h.has_value()) << ext << ": " << error;
    EXPECT_EQ(h->width, 37) << ext;
    EXPECT_EQ(h->height, 23) << ext;
    const DecodedImage d = DecodeImage(encoded.data(), encoded.size(), ImageReadOptions(), ext);
    EXPECT_EQ(d.error, "") << ext;
    EXPECT_EQ(d.image.size(), cv::Size(37, 23)) << ext;
    EXPECT_EQ(d.image.type(), CV_8UC3) << ext;
  }
  EXPECT_GE(formats, 6);
  // Headers written by hand: PFM, a BMP stored top-down, an OS/2 BMP, PNM
  // with comments, WebP's lossless and extended forms.
  EXPECT_EQ(Header("PF\n37 23\n-1.0\n")->width, 37);
  auto bmp = Header("BM" + std::string(12, '\0') + Le32(40) + Le32(37) + Le32(static_cast<uint32_t>(-23)));
  ASSERT_TRUE(bmp);
  EXPECT_EQ(bmp->height, 23);
  bmp = Header("BM" + std::string(12, '\0') + Le32(12) + Le16(37) + Le16(23));
  ASSERT_TRUE(bmp);
  EXPECT_EQ(bmp->width, 37);
  const auto pnm = Header("P6\n# a comment\n  50000 # another\n 40000\n255\n");
  ASSERT_TRUE(pnm);
  EXPECT_EQ(pnm->width, 50000);
  EXPECT_EQ(pnm->height, 40000);
  const uint32_t bits = (37 - 1) | ((23 - 1) << 14);
  const auto lossless = Header("RIFF" + Le32(100) + "WEBPVP8L" + Le32(50) + "\x2f" + Le32(bits));
  ASSERT_TRUE(lossless);
  EXPECT_EQ(lossless->height, 23);
  const auto extended =
      Header("RIFF" + Le32(100) + "WEBPVP8X" + Le32(10) + Le32(0) + std::string("\xff\x3f\x00\xff\x3f\x00", 6));
  ASSERT_TRUE(extended);
  EXPECT_EQ(extended->width, 16384);
}

TEST(ImageReadTest, MalformedAndUnknownHeadersAreNotDecoded) {
  std::string error;
  for (const auto& [bytes, phrase] : std::vector<std::pair<std::string, std::string>>{
           {"", "empty"},
           {std::string("\x89PNG\r\n\x1a\n", 8), "IHDR"},
           {PngHeader(0, 10), "impossible size 0 x 10"},
           {PngHeader(0x80000000u, 10), "impossible size"},
           {std::string("\xff\xd8\xff\xe0\x00\x10JFIF", 10), "cut short"},
           {std::string("\xff\xd8\xff\xda\x00\x02", 6), "no frame header"},
           {"BM" + std::string(6, '\0'), "BMP"},
           {"P6\n12", "PNM"},
           {"P7\nWIDTH 5\n", "PAM"},
           {"GIF89a" + std::string(20, '\0'), "not an image format placedb reads"},
           {std::string("II*\0", 4) + std::string(20, '\0'), "not an image format"},  // TIFF
           {"RIFF" + Le32(100) + "WEBPVP8 " + std::string(20, '\0'), "WebP"}}) {
    EXPECT_FALSE(Header(bytes, &error)) << phrase;
    EXPECT_NE(error.find(phrase), std::string::npos) << error;
    const DecodedImage d = DecodeImage(reinterpret_cast<const uint8_t*>(bytes.data()),
                                       bytes.size(), ImageReadOptions(), "x");
    EXPECT_TRUE(d.image.empty());
    EXPECT_FALSE(d.too_large);
    EXPECT_NE(d.error.find(phrase), std::string::npos) << d.error;
  }
}

// The probe's bombs: a 30000 x 30000 PNG, a JPEG of 65535 x 65535 behind
// APP segments, a PNM: refused from the header, nothing decoded.
TEST(ImageReadTest, ImagesLargerThanTheBoundAreRefusedBeforeDecoding) {
  const std::string jpeg = std::string("\xff\xd8\xff\xe1", 4) + Be32(0x10).substr(2) +
                           std::string(14, 'x') + std::string("\xff\xc2\x00\x11\x08", 5) +
                           Be32(0xffffffffu) + std::string(12, '\0');
  for (const std::string& bytes :
       {PngHeader(30000, 30000), jpeg, std::string("P5 8000 5001 255\n"),
        "BM" + std::string(12, '\0') + Le32(40) + Le32(40000) + Le32(1001)}) {
    const DecodedImage d = DecodeImage(reinterpret_cast<const uint8_t*>(bytes.data()),
                                       bytes.size(), ImageReadOptions(), "bomb");
    EXPECT_TRUE(d.too_large) << d.error;
    EXPECT_TRUE(d.image.empty());
    EXPECT_NE(d.error.find("more than the 40000000 pixels allowed"), std::string::npos)
        << d.error;
  }
  // The bound is an option: 40 000 000 pixels exactly pass the check.
  ImageReadOptions small;
  small.max_pixels = 37 * 23 - 1;
  cv::Mat image(23, 37, CV_8UC3, cv::Scalar(1, 2, 3));
  std::vector<uint8_t> png;
  cv::imencode(".png", image, png);
  EXPECT_TRUE(DecodeImage(png.data(), png.size(), small, "small").too_large);
  small.max_pixels = 37 * 23;
  EXPECT_EQ(DecodeImage(png.data(), png.size(), small, "small").image.size(), image.size());
  // Its range.
  ImageReadOptions bad;
  bad.max_pixels = 0;
  EXPECT_NE(bad.Check(), "");
  bad.max_pixels = (int64_t{1} << 30) + 1;
  EXPECT_NE(bad.Check(), "");
  bad.max_pixels = int64_t{1} << 30;
  EXPECT_EQ(bad.Check(), "");
  EXPECT_EQ(ImageReadOptions().max_pixels, 40000000);
}

TEST(ImageReadTest, FramesAndFilesGoThroughTheBound) {
  TempDir tmp;
  const std::string bomb = tmp.Write("bomb.png", PngHeader(30000, 30000));
  Frame frame;
  frame.id = 7;
  frame.image_path = bomb;
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { LoadFrameImage(frame); },
                                          {"frame 7", "30000 x 30000", "more than"}));
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { ReadImageFile(bomb, ImageReadOptions()); },
                                          "more than the 40000000 pixels allowed"));
  // A missing image is NotFound, a file that is not an image InvalidArgument.
  EXPECT_TRUE(ThrowsWith<NotFound>(
      [&] { ReadImageFile(tmp.Path("missing.png"), ImageReadOptions()); }, "missing.png"));
  const std::string text = tmp.Write("text.png", "not an image");
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { ReadImageFile(text, ImageReadOptions()); },
                                          {"cannot read image", "text.png"}));
  // A simulated camera larger than the bound.
  frame.image_path = RtabmapImage(1);
  frame.resize_to = cv::Size(16384, 16384);
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { LoadFrameImage(frame); },
                                          "simulated camera size 16384x16384"));
  frame.resize_to = cv::Size(160, 120);
  EXPECT_EQ(LoadFrameImage(frame).size(), cv::Size(160, 120));
  // Decoded as cv::imread decodes (JPEG and PNG of the sample data).
  for (const std::string& path :
       {RtabmapImage(3), std::string(PLACEDB_DATA_DIR "/oxford_graf/graf1.png")}) {
    const cv::Mat mine = ReadImageFile(path, ImageReadOptions());
    const cv::Mat theirs = cv::imread(path, cv::IMREAD_COLOR);
    ASSERT_EQ(mine.size(), theirs.size()) << path;
    EXPECT_EQ(cv::norm(mine, theirs, cv::NORM_INF), 0.0) << path;
  }
  // Not regular files: an error, never a wait (a FIFO with no writer).
  ASSERT_EQ(::mkfifo(tmp.Path("fifo").c_str(), 0600), 0);
  for (const std::string& path : {tmp.Path("fifo"), tmp.Path()}) {
    const DecodedImage d = TryReadImageFile(path, ImageReadOptions());
    EXPECT_NE(d.error.find("not a regular file"), std::string::npos) << d.error;
  }
  EXPECT_NE(TryReadImageFile(tmp.Path("missing.png"), ImageReadOptions()).error.find(
                "No such file"),
            std::string::npos);
  // A missing or undecodable frame is unreadable (empty), as before.
  Frame missing;
  missing.image_path = tmp.Path("missing.png");
  EXPECT_TRUE(LoadFrameImage(missing).empty());
  missing.image_path = tmp.Write("text.png", "not an image");
  EXPECT_TRUE(LoadFrameImage(missing).empty());
}

}  // namespace
}  // namespace placedb
