// The keyframe file, format version 3 (this placedb writes it; it reads 2
// and 3): what a database keeps of its keyframes, in flat little-endian
// sections that are used in place from a memory map.
//
//   header (64 bytes)
//     char[8] magic "PLDBKF\r\n" (the CR LF catches text-mode mangling)
//     u32 format version (2 or 3)  u32 header bytes (64)
//     u32 feature type (1 ORB, 2 SURF)   u32 descriptor bytes per row
//     u32 number of sections S (4..16)   u32 reserved (0)
//     u64 keyframes K   u64 features F   u64 file bytes
//     u64 checksum: XXH3-64 of header bytes [0, 56) followed by the section table
//   section table: S entries of 32 bytes
//     u32 kind   u32 reserved (0)   u64 offset   u64 bytes   u64 XXH3-64 of the section
//   sections, each at a multiple of 64 bytes, in any order, not overlapping:
//     1 keyframes    K records of 152 bytes (see kKeyframe* offsets)
//     2 strings      the keyframes' source paths and image names
//     3 keypoints    version 2 only: F records of 28 bytes, the layout of
//                    cv::KeyPoint (x, y, size, angle, response: f32;
//                    octave, class_id: i32)
//     4 descriptors  F rows of descriptor bytes each
//     5 source hashes  K u64, keyframe i's Keyframe::source_hash (0: not
//                    recorded). Optional: files of earlier placedb versions
//                    lack it, and their keyframes read with hash 0 (a
//                    reader of that time skips it as an unknown kind, so
//                    the format version stays 2).
//     6 whole image  the whole-image channel (feature/whole_image.h): a
//                    64-byte preamble (u32 values per row D in [16, 4096],
//                    then 60 bytes of 0), then K rows of D int8 values in
//                    [-127, 127], keyframe i's at preamble end + i D.
//                    Optional, like section 5: files without it read with
//                    no whole-image channel (Database::whole_image_dims()
//                    0), earlier readers skip it, and the manifest's
//                    `whole_image_dims` (absent: 0) must agree with it.
//     7 compact keypoints  version 3 only: a 64-byte preamble (u32 record
//                    bytes 10, u32 position fraction bits 3, then 56 bytes
//                    of 0), then F records of 10 bytes
//                    (storage/compact_keypoint.h)
//     8 feature blocks  version 3 only: K pairs of u64, keyframe i's
//                    XXH3-64 of its compact keypoint records and of its
//                    descriptor rows. What lets a reader check a keyframe's
//                    features when they are first used instead of hashing
//                    every byte on open (Database, "Integrity").
//   Version 2 needs kinds 1 to 4, version 3 kinds 1, 2, 4, 7 and 8.
//   Unknown section kinds are skipped (their checksums are not verified).
//
// Keyframe i owns features [feature_offset, feature_offset + feature_count),
// the keyframes' ranges back to back in keyframe order. SURF rows of a
// keyframe are grouped by the sign of the Laplacian: the first
// positive_count have class_id >= 0, the rest class_id < 0.
//
// The header checksum covers the section table, which holds every section's
// checksum: the manifest records it (and the file's name and size), which
// binds the manifest to this one file.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace placedb {
namespace keyframe_file {

constexpr char kMagic[8] = {'P', 'L', 'D', 'B', 'K', 'F', '\r', '\n'};
constexpr uint32_t kVersion = 3;        // written
constexpr uint32_t kOldestVersion = 2;  // still read
constexpr size_t kHeaderBytes = 64;
constexpr size_t kChecksumOffset = 56;
constexpr size_t kSectionEntryBytes = 32;
constexpr uint32_t kMinSections = 4;
constexpr uint32_t kMaxSections = 16;
constexpr size_t kSectionAlignment = 64;
constexpr size_t kKeyframeRecordBytes = 152;
constexpr size_t kKeypointRecordBytes = 28;

enum SectionKind : uint32_t {
  kKeyframes = 1,
  kStrings = 2,
  kKeypoints = 3,
  kDescriptors = 4,
  kSourceHashes = 5,  // optional
  kWholeImage = 6,    // optional
  kCompactKeypoints = 7,
  kFeatureBlocks = 8,
};
constexpr uint32_t kLastKind = kFeatureBlocks;
// The compact keypoint section's preamble, and a feature block entry.
constexpr size_t kCompactKeypointPreambleBytes = 64;
constexpr size_t kFeatureBlockEntryBytes = 16;
// The whole-image section: its preamble, and the row sizes it may hold.
constexpr size_t kWholeImagePreambleBytes = 64;
constexpr uint32_t kMinWholeImageDims = 16;    // 4 x 4
constexpr uint32_t kMaxWholeImageDims = 4096;  // 64 x 64

// Recomputes the checksums of a keyframe file image, as far as its section
// table can be read: in version 3 the feature block checksums of the
// keyframes whose records and sections can be read, then every readable
// section's checksum, then the header
// checksum; with `fix_size`, the header's file bytes too. For tests that
// mutate a valid file so that the parser itself, not the checksums, must
// catch the damage. Returns the header checksum (0 if the header is short).
uint64_t Reseal(std::string* bytes, bool fix_size);

}  // namespace keyframe_file
}  // namespace placedb
