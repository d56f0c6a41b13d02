// ROS bags (format 2.0) read record by record by placedb itself, so that a
// damaged or crafted bag is refused with one line before anything is
// allocated for it. rosbag_storage trusts the sizes a bag states (a record
// header of 4 GiB is allocated, then an assertion aborts; an index offset
// is read past its chunk), and ROS's deserialization resizes a vector to the
// length a message states before it checks the bytes are there.
//
// What is checked, against the record and the file that hold it: every
// record's header and data length, every header field's length and width,
// the ops (file header first, then chunks with their index records, then
// the connections and chunk infos the file header points to), a chunk's
// compression (none, bz2, lz4) and its stated size (at most
// kMaxBagChunkBytes; the decompressed bytes must be exactly that many), the
// records inside each chunk (connections and messages only), every message's
// connection, the index records' counts against their lengths, the chunk
// infos' positions. A message's own bytes are checked by its reader
// (ReadImageMessage and the like, bag_source.cc) before ROS deserializes
// them.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace placedb {

// The largest chunk (decompressed) a bag may hold: rosbag record writes
// chunks of 768 KiB, and a chunk holds one message when it is larger (a raw
// 4K frame is 24 MiB).
constexpr uint32_t kMaxBagChunkBytes = 1u << 30;
// The largest record header: the fields of a connection, a message, a
// chunk (a few dozen bytes each).
constexpr uint32_t kMaxBagRecordHeaderBytes = 1u << 20;

struct BagConnection {
  uint32_t id = 0;
  std::string topic, type, md5sum;
};

// A message's place in the bag.
struct BagMessage {
  uint32_t connection = 0;     // its BagConnection's id
  uint32_t sec = 0, nsec = 0;  // when it was recorded
  uint32_t chunk = 0;          // index of its chunk, in file order
  uint32_t offset = 0;         // of its bytes in the decompressed chunk
  uint32_t size = 0;
  double time() const { return sec + nsec * 1e-9; }
};

class BagReader {
 public:
  // Called for every message, in file order, with its connection and its
  // serialized bytes (valid during the call).
  using Visitor =
      std::function<void(const BagMessage&, const BagConnection&, const uint8_t*, size_t)>;

  // Reads and checks the whole bag at `path`, calling `visit` for each
  // message. NotFound when there is no file, IoError when a read fails,
  // InvalidArgument (naming the bag and the byte) when it is not a
  // well-formed bag of format 2.0; what `visit` throws passes through.
  BagReader(const std::string& path, const Visitor& visit);
  ~BagReader();
  BagReader(const BagReader&) = delete;
  BagReader& operator=(const BagReader&) = delete;

  const std::string& path() const { return path_; }
  // Every connection, by first appearance.
  const std::vector<BagConnection>& connections() const { return connections_; }
  const BagConnection* FindConnection(uint32_t id) const;

  // The serialized bytes of `m`, a message the constructor visited: its
  // chunk is read and decompressed again (the last one is kept). The file
  // is checked again on the way (it may have changed since): a chunk that no
  // longer holds the message is InvalidArgument. Thread-safe.
  std::string ReadMessage(const BagMessage& m) const;

 private:
  struct Chunk {
    uint64_t data_pos = 0;
    uint32_t data_len = 0;
    uint32_t size = 0;  // decompressed
    int compression = 0;
  };
  // The decompressed bytes of chunk `index`, read from the file.
  void LoadChunk(const Chunk& chunk, uint64_t record_pos, std::string* out) const;

  std::string path_;
  int fd_ = -1;
  uint64_t file_size_ = 0;
  std::vector<Chunk> chunks_;
  std::vector<uint64_t> chunk_positions_;  // of each chunk's record
  std::vector<BagConnection> connections_;
  mutable std::mutex cache_mutex_;
  mutable int64_t cached_chunk_ = -1;
  mutable std::string cached_;
};

}  // namespace placedb
