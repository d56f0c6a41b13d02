#include "placedb/util/checksum.h"

#include <fmt/format.h>

// XXH3_state_t's definition, for the stream's state; the _dispatch entry
// points run the CPU's widest vector code (the same hashes on any CPU).
#define XXH_STATIC_LINKING_ONLY
#include <xxhash.h>
#if defined(__x86_64__) || defined(__i386__)
#include <xxh_x86dispatch.h>
#define PLACEDB_XXH3(data, size) XXH3_64bits_dispatch(data, size)
#define PLACEDB_XXH3_UPDATE(state, data, size) XXH3_64bits_update_dispatch(state, data, size)
#else
#define PLACEDB_XXH3(data, size) XXH3_64bits(data, size)
#define PLACEDB_XXH3_UPDATE(state, data, size) XXH3_64bits_update(state, data, size)
#endif

namespace placedb {

uint64_t Checksum64(const void* data, size_t size) { return PLACEDB_XXH3(data, size); }

struct Checksum64Stream::State {
  XXH3_state_t state;
};

Checksum64Stream::Checksum64Stream() : state_(std::make_unique<State>()) {
  XXH3_64bits_reset(&state_->state);
}

Checksum64Stream::~Checksum64Stream() = default;

void Checksum64Stream::Update(const void* data, size_t size) {
  PLACEDB_XXH3_UPDATE(&state_->state, data, size);
}

uint64_t Checksum64Stream::Digest() const { return XXH3_64bits_digest(&state_->state); }

std::string ChecksumHex(uint64_t checksum) { return fmt::format("{:016x}", checksum); }

}  // namespace placedb
