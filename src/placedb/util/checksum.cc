#include "placedb/util/checksum.h"

#include <fmt/format.h>

#define XXH_INLINE_ALL
#include <xxhash.h>

namespace placedb {

uint64_t Checksum64(const void* data, size_t size) { return XXH3_64bits(data, size); }

struct Checksum64Stream::State {
  XXH3_state_t state;
};

Checksum64Stream::Checksum64Stream() : state_(std::make_unique<State>()) {
  XXH3_64bits_reset(&state_->state);
}

Checksum64Stream::~Checksum64Stream() = default;

void Checksum64Stream::Update(const void* data, size_t size) {
  XXH3_64bits_update(&state_->state, data, size);
}

uint64_t Checksum64Stream::Digest() const { return XXH3_64bits_digest(&state_->state); }

std::string ChecksumHex(uint64_t checksum) { return fmt::format("{:016x}", checksum); }

}  // namespace placedb
