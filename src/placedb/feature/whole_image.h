// The whole-image channel: a compact descriptor of a whole frame, SeqSLAM's
// patch-normalised thumbnail (Milford and Wyeth, ICRA 2012), and the cosine
// similarity of two of them, with its hot loop over many stored rows.
//
// The descriptor: the frame in grey, resized by area to width x height;
// each patch x patch tile (the tiles at the right and bottom edges may be
// smaller: the tiles cover the whole thumbnail) minus its mean, divided by
// its standard deviation (a flat tile, std < 1e-6 grey levels, is all
// zeros); z clamped to [-4, 4] and stored as round(31.75 z): int8 values in
// [-127, 127], one row of width x height. Brightness and contrast changes
// (an affine change of the grey levels) leave it nearly unchanged.
#pragma once

#include <cstddef>
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>

#include "placedb/feature/options.h"

namespace placedb {

// The descriptor of an 8-bit grey, BGR or BGRA image: a 1 x (width *
// height) CV_8S row, values in [-127, 127]. Deterministic. InvalidArgument
// for an empty image, one that is not 8-bit, or options that do not pass
// Check().
cv::Mat ComputeWholeImageDescriptor(const cv::Mat& image, const WholeImageOptions& o);

// The cosine of two rows of `dims` int8 values: sum(ab) / sqrt(sum(a^2)
// sum(b^2)), in [-1, 1]; 0 when either row is all zeros.
double WholeImageSimilarity(const int8_t* a, const int8_t* b, int dims);

// The cosine of `query` with each of `count` rows stored back to back (row i
// at rows + i * dims), into out[i]: one pass over the rows, int32 dot
// products and the rows' squared norms together. Values must be in [-127,
// 127] (what ComputeWholeImageDescriptor gives, and the database accepts);
// dims in [1, 2^16]. The kernel is chosen once from the CPU's features
// (AVX-VNNI, else AVX2, else the reference); every kernel gives the same
// numbers.
void WholeImageSimilarities(const int8_t* query, const int8_t* rows, size_t count, int dims,
                            float* out);

// The kernels, for tests and benchmarks. Each returns with the upper vector
// state clean (vzeroupper).
enum class WholeImageKernel { kReference = 0, kAvx2 = 1, kAvxVnni = 2 };
constexpr int kNumWholeImageKernels = 3;
const char* WholeImageKernelName(WholeImageKernel kernel);
bool WholeImageKernelAvailable(WholeImageKernel kernel);
// The kernel WholeImageSimilarities uses on this CPU.
WholeImageKernel ActiveWholeImageKernel();
// WholeImageSimilarities with the kernel given (it must be available).
void WholeImageSimilaritiesWith(WholeImageKernel kernel, const int8_t* query, const int8_t* rows,
                                size_t count, int dims, float* out);

}  // namespace placedb
