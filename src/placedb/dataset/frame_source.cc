#include "placedb/dataset/frame_source.h"

#include <cmath>
#include <string>

#include "placedb/dataset/image_folder.h"
#include "placedb/util/check.h"

namespace placedb {

cv::Size ParseFrameSize(const std::string& text, const std::string& name) {
  const size_t x = text.find('x');
  int w = 0, h = 0;
  bool ok = x != std::string::npos && x > 0 && x + 1 < text.size();
  if (ok) {
    for (size_t i = 0; i < text.size(); ++i) {
      if (i != x && (text[i] < '0' || text[i] > '9')) ok = false;
    }
  }
  if (ok && x <= 5 && text.size() - x - 1 <= 5) {
    w = std::stoi(text.substr(0, x));
    h = std::stoi(text.substr(x + 1));
  } else {
    PLACEDB_THROW_INVALID("`", name, "` takes WxH, e.g. 160x120 (got '", text, "')");
  }
  if (w < 16 || h < 16 || w > 16384 || h > 16384)
    PLACEDB_THROW_INVALID("`", name, "`: each side must be in [16, 16384] (got ", text, ")");
  return {w, h};
}

const OptionTable<FrameSourceOptions>& FrameSourceOptions::Table() {
  static const OptionTable<FrameSourceOptions> table = [] {
    using O = FrameSourceOptions;
    OptionTable<O> t("frame source");
    t.String("images", PLACEDB_MEMBER(O, images),
             "a folder of images (sorted by name) or a text file listing image paths", kCallers);
    t.String("tum", PLACEDB_MEMBER(O, tum), "a TUM RGB-D folder (rgb.txt, groundtruth.txt)",
             kCallers);
    t.Number("first", PLACEDB_MEMBER(O, first), OptionRange::RightOpen(1, 2147483648.0),
             "first frame to use, its 1-based position in the listing (build: also its id)", kCallers);
    t.Number("last", PLACEDB_MEMBER(O, last), OptionRange::RightOpen(0, 2147483648.0),
             "last frame to use, its 1-based position in the listing (0: to the end)", kCallers);
    OptionField size;
    size.name = "frame_size";
    size.member = "frame_size";
    size.kind = OptionKind::kText;
    size.help =
        "resize every frame to WxH as it is read, to see how a smaller camera does (e.g. "
        "160x120); '': as stored";
    size.range = "each side in [16, 16384], W x H at most `max_image_pixels`";
    size.surfaces = kCallers;
    t.Custom(
        &O::frame_size, size,
        [](const O& o) -> OptionValue {
          if (o.frame_size.empty()) return std::string();
          return std::to_string(o.frame_size.width) + "x" + std::to_string(o.frame_size.height);
        },
        [](O& o, const OptionValue& v) {
          if (const auto* n = std::get_if<std::vector<double>>(&v)) {
            if (n->empty()) {
              o.frame_size = cv::Size();
              return;
            }
            if (n->size() != 2 || (*n)[0] != std::floor((*n)[0]) ||
                (*n)[1] != std::floor((*n)[1]) || !((*n)[0] >= 16 && (*n)[0] <= 16384) ||
                !((*n)[1] >= 16 && (*n)[1] <= 16384)) {
              PLACEDB_THROW_INVALID(
                  "`frame_size` takes (width, height), each a whole number in [16, 16384]");
            }
            o.frame_size = cv::Size(static_cast<int>((*n)[0]), static_cast<int>((*n)[1]));
            return;
          }
          const std::string text = option_table_internal::ToString(v, "frame_size");
          o.frame_size = text.empty() ? cv::Size() : ParseFrameSize(text, "frame_size");
        },
        [](const O& o) -> std::string {
          if (o.frame_size.empty()) return "";
          const cv::Size s = o.frame_size;
          if (s.width < 16 || s.height < 16 || s.width > 16384 || s.height > 16384)
            return "`frame_size`: each side must be in [16, 16384]";
          const int64_t pixels = static_cast<int64_t>(s.width) * s.height;
          if (pixels > o.image_read.max_pixels) {
            return "`frame_size` " + std::to_string(s.width) + "x" + std::to_string(s.height) +
                   " is " + std::to_string(pixels) + " pixels, more than `max_image_pixels` " +
                   std::to_string(o.image_read.max_pixels);
          }
          return "";
        });
    t.Nest(PLACEDB_MEMBER(O, tum_options), TumOptions::Table(), kCallers);
    t.Nest(PLACEDB_MEMBER(O, image_read), ImageReadOptions::Table(), kCallers);
    t.Rule([](const O& o) -> std::string {
      if (o.last != 0 && o.last < o.first) return "`last` must be 0 or at least `first`";
      if (!o.images.empty() && !o.tum.empty()) return "give `images` or `tum`, not both";
      return "";
    });
    return t;
  }();
  return table;
}

std::string FrameSourceOptions::Check() const { return Table().Check(*this); }

std::vector<Frame> ReadFrames(const FrameSourceOptions& source) {
  PLACEDB_CHECK_OPTIONS(source);
  std::vector<Frame> frames;
  if (!source.images.empty()) {
    frames = ReadImages(source.images, source.first, source.last);
  } else if (!source.tum.empty()) {
    frames = SelectFrameRange(ReadTumSequence(source.tum, source.tum_options), source.first,
                              source.last, "TUM frame");
  } else {
    PLACEDB_THROW_INVALID("give `images` (a folder or list of images) or `tum` (a TUM folder)");
  }
  SetImageReadOptions(&frames, source.image_read);
  if (!source.frame_size.empty()) ResizeFramesTo(&frames, source.frame_size);
  return frames;
}

std::string DescribeFrameSource(const FrameSourceOptions& source) {
  const std::string what = !source.images.empty() ? "images:" + source.images : "tum:" + source.tum;
  const std::string size = source.frame_size.empty()
                               ? ""
                               : " at " + std::to_string(source.frame_size.width) + "x" +
                                     std::to_string(source.frame_size.height);
  return what + FrameRangeSuffix(source.first, source.last) + size;
}

}  // namespace placedb
