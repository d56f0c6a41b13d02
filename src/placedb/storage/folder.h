// Who may write and remove what in a database folder.
//
// The rule for reads: opening a database, querying it, verifying it, `info`,
// `eval`, the Python module's reads, the ROS workers and voter write nothing
// and delete nothing, in the folder or anywhere else.
//
// The rule for debris (what a writer killed mid-way left): it is removed
// only by a writer that holds the folder's DirectoryLock (a session's first
// change and its Save, a build for its own output), and only files whose
// names are what a placedb writer creates:
//   - in the folder: temporary files (TempPathFor's "<name>.tmp.<pid>.<n>")
//     of processes that are gone; keyframe files other than the current one;
//     index files the caller says are stale;
//   - in images/: temporary files of processes that are gone, and files
//     named as placedb names stored images (StoredImageFileName: digits and
//     ".png") that no keyframe of the current generation names;
//   - beside the folder: "<folder>.building.<pid>" directories of builds
//     whose process is gone.
// images/ must be a real directory of the folder: it is opened without
// following a symlink (O_NOFOLLOW) and every removal is relative to its
// descriptor (unlinkat of a regular file), so nothing outside the folder is
// ever reached. A writer also refuses to store images into an images/ that
// is a symlink (StoredImageFolderForWriting).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "placedb/util/file_io.h"

namespace placedb {

class Database;

// "images/000042.png": the stored image of keyframe `id` (>= 1), as the
// builder and a session's Add name it.
std::string StoredImageFileName(int32_t id);
// Whether `name` (a file name inside images/) is one StoredImageFileName
// gives: six to ten digits and ".png".
bool IsPlacedbStoredImageName(const std::string& name);

// Removes the debris of the folder `dir` whose current generation is
// `current` (see the rule above). `stale_index(name)` says whether a file of
// the folder is an index file of another generation. The caller holds the
// folder's lock. Best effort: an error skips a file. Returns how many were
// removed.
size_t SweepDatabaseDebris(const std::string& dir, const Database& current,
                           const std::function<bool(const std::string&)>& stale_index);

// Removes the "<dir>.building.<pid>" directories (real directories, not
// symlinks) beside `dir` whose process is gone, or is this one when
// `include_own`. Returns how many.
size_t RemoveAbandonedBuilds(const std::string& dir, bool include_own);

// The database's own images/ folder, opened for a writer that stores images
// there: created when missing; InvalidArgument when it is a symlink or not a
// directory (naming the path, and what to do); IoError when it cannot be
// created or opened.
std::unique_ptr<DirectoryHandle> StoredImageFolderForWriting(const std::string& dir);

}  // namespace placedb
