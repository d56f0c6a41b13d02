// Frames from a folder of images or from a text file listing image paths.
// These sources have no timestamps (-1) and no poses.
#pragma once

#include <string>
#include <vector>

#include "placedb/dataset/frame.h"

namespace placedb {

// Image files directly inside `dir` (extensions jpg jpeg png bmp ppm pgm tif
// tiff webp, case-insensitive; hidden files, i.e. names starting with '.', are
// ignored), sorted by file name (byte order). A frame's id is its 1-based
// position in that sorted listing; `first`/`last` (1-based, inclusive; last = 0
// means to the end) select a range, ids unchanged. A `last` beyond the listing
// is clamped with a warning.
// Errors naming `dir`: NotFound for a missing dir; InvalidArgument for no
// images, first < 1, last < 0, first > last, first beyond the listing.
std::vector<Frame> ListImageFolder(const std::string& dir, int first = 1, int last = 0);

// A text file listing one image path per line (relative paths are relative to
// the list file's folder; leading/trailing blanks trimmed; blank lines and
// lines starting with '#' skipped). id = 1-based position among the listed
// images; `first`/`last` as above. A listed image that does not exist is kept
// with a warning (names list file and line). Errors: NotFound for a missing
// list file, IoError for an unreadable one, InvalidArgument for no images or
// a bad range.
std::vector<Frame> ReadImageList(const std::string& list_file, int first = 1, int last = 0);

// Either of the two: a directory → ListImageFolder, a regular file →
// ReadImageList; nothing there → NotFound; anything else → InvalidArgument.
std::vector<Frame> ReadImages(const std::string& path, int first = 1, int last = 0);

}  // namespace placedb
