#include "placedb/dataset/bag/bag_reader.h"

#include <bzlib.h>
#include <fcntl.h>
#include <roslz4/lz4s.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <map>
#include <optional>
#include <string_view>

#include "placedb/util/check.h"
#include "placedb/util/file_io.h"

namespace placedb {
namespace {

constexpr char kMagic[] = "#ROSBAG V2.0\n";
constexpr size_t kMagicBytes = sizeof(kMagic) - 1;

enum Op : uint8_t {
  kMessageData = 0x02,
  kBagHeader = 0x03,
  kIndexData = 0x04,
  kChunk = 0x05,
  kChunkInfo = 0x06,
  kConnection = 0x07,
};

enum Compression { kNone = 0, kBz2 = 1, kLz4 = 2 };

uint32_t Le32(const uint8_t* p) {
  uint32_t v;
  std::memcpy(&v, p, 4);
  return v;
}
uint64_t Le64(const uint8_t* p) {
  uint64_t v;
  std::memcpy(&v, p, 8);
  return v;
}

// Where a check failed: "<what> at byte <n>".
[[noreturn]] void Bad(const std::string& path, uint64_t at, const std::string& what) {
  PLACEDB_THROW_INVALID("the bag ", path, " is damaged or not a ROS bag (format 2.0): ", what,
                        " at byte ", at);
}

// A record header's fields: name=value, each with its 4-byte length.
class Fields {
 public:
  Fields(const std::string& path, uint64_t at, std::string_view bytes) : path_(path), at_(at) {
    size_t i = 0;
    while (i < bytes.size()) {
      if (bytes.size() - i < 4) Bad(path_, at_ + i, "a header field's length is cut short");
      const uint32_t n = Le32(reinterpret_cast<const uint8_t*>(bytes.data() + i));
      i += 4;
      if (n > bytes.size() - i) Bad(path_, at_ + i, "a header field is longer than its header");
      const std::string_view field = bytes.substr(i, n);
      const size_t eq = field.find('=');
      if (eq == std::string_view::npos || eq == 0)
        Bad(path_, at_ + i, "a header field has no name");
      fields_[std::string(field.substr(0, eq))] = field.substr(eq + 1);
      i += n;
    }
  }
  bool Has(const char* name) const { return fields_.count(name) > 0; }
  std::string_view Raw(const char* name, size_t width) const {
    const auto it = fields_.find(name);
    if (it == fields_.end()) Bad(path_, at_, std::string("the header has no '") + name + "' field");
    if (width > 0 && it->second.size() != width) {
      Bad(path_, at_,
          std::string("the header field '") + name + "' is not " + std::to_string(width) +
              " bytes");
    }
    return it->second;
  }
  uint8_t U8(const char* name) const { return static_cast<uint8_t>(Raw(name, 1)[0]); }
  uint32_t U32(const char* name) const {
    return Le32(reinterpret_cast<const uint8_t*>(Raw(name, 4).data()));
  }
  uint64_t U64(const char* name) const {
    return Le64(reinterpret_cast<const uint8_t*>(Raw(name, 8).data()));
  }
  std::string String(const char* name) const { return std::string(Raw(name, 0)); }

 private:
  const std::string& path_;
  uint64_t at_;
  std::map<std::string, std::string_view> fields_;
};

// A record's place: its header's bytes and its data's position and length.
struct Record {
  uint64_t pos = 0;  // of the record
  std::string header;
  uint64_t data_pos = 0;
  uint32_t data_len = 0;
  uint64_t end() const { return data_pos + data_len; }
};

// A record inside a decompressed chunk (`bytes`), at `pos`; the chunk is at
// byte `base` of the file (for messages).
struct InnerRecord {
  std::string_view header;
  size_t data_pos = 0;
  uint32_t data_len = 0;
};

InnerRecord ReadInnerRecord(const std::string& path, uint64_t base, std::string_view bytes,
                            size_t pos) {
  InnerRecord r;
  if (bytes.size() - pos < 4) Bad(path, base, "a record in a chunk is cut short");
  const uint32_t header_len = Le32(reinterpret_cast<const uint8_t*>(bytes.data() + pos));
  if (header_len > bytes.size() - pos - 4 || bytes.size() - pos - 4 - header_len < 4) {
    Bad(path, base, "a record in a chunk is longer than its chunk");
  }
  r.header = bytes.substr(pos + 4, header_len);
  r.data_len = Le32(reinterpret_cast<const uint8_t*>(bytes.data() + pos + 4 + header_len));
  r.data_pos = pos + 8 + header_len;
  if (r.data_len > bytes.size() - r.data_pos) {
    Bad(path, base, "a record's data in a chunk is longer than its chunk");
  }
  return r;
}

}  // namespace

BagReader::BagReader(const std::string& path, const Visitor& visit) : path_(path) {
  fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NOCTTY | O_NONBLOCK);
  if (fd_ < 0) PLACEDB_THROW_READ_ERROR(errno, "cannot open the bag ", path);
  try {
    struct stat st;
    if (::fstat(fd_, &st) != 0)
      PLACEDB_THROW_IO("cannot read the bag ", path, ": ", std::strerror(errno));
    if (!S_ISREG(st.st_mode)) PLACEDB_THROW_INVALID("the bag ", path, " is not a file");
    file_size_ = static_cast<uint64_t>(st.st_size);

    auto read_at = [&](uint64_t pos, void* out, size_t n) {
      size_t done = 0;
      while (done < n) {
        const ssize_t got =
            ::pread(fd_, static_cast<char*>(out) + done, n - done, static_cast<off_t>(pos + done));
        if (got < 0 && errno == EINTR) continue;
        if (got < 0) PLACEDB_THROW_IO("cannot read the bag ", path, ": ", std::strerror(errno));
        if (got == 0) Bad(path, pos + done, "the file ends early");
        done += static_cast<size_t>(got);
      }
    };
    // A top-level record at `pos`: its lengths within the file.
    auto read_record = [&](uint64_t pos) {
      Record r;
      r.pos = pos;
      if (file_size_ - pos < 8) Bad(path, pos, "a record is cut short");
      uint8_t len[4];
      read_at(pos, len, 4);
      const uint32_t header_len = Le32(len);
      if (header_len > kMaxBagRecordHeaderBytes) {
        Bad(path, pos,
            "a record header of " + std::to_string(header_len) + " bytes (at most " +
                std::to_string(kMaxBagRecordHeaderBytes) + ")");
      }
      if (header_len > file_size_ - pos - 8)
        Bad(path, pos, "a record header runs past the file's end");
      r.header.resize(header_len);
      read_at(pos + 4, r.header.data(), header_len);
      read_at(pos + 4 + header_len, len, 4);
      r.data_len = Le32(len);
      r.data_pos = pos + 8 + header_len;
      if (r.data_len > file_size_ - r.data_pos)
        Bad(path, pos, "a record's data runs past the file's end");
      return r;
    };

    char magic[kMagicBytes];
    if (file_size_ < kMagicBytes) Bad(path, 0, "the file is shorter than a bag's first line");
    read_at(0, magic, kMagicBytes);
    if (std::memcmp(magic, kMagic, kMagicBytes) != 0) {
      Bad(path, 0, "the first line is not '#ROSBAG V2.0' (bags of format 1.2 are not read)");
    }
    const Record first = read_record(kMagicBytes);
    const Fields bag_header(path, first.pos, first.header);
    if (bag_header.U8("op") != kBagHeader)
      Bad(path, first.pos, "the first record is not the bag header");
    const uint64_t index_pos = bag_header.U64("index_pos");
    const uint32_t conn_count = bag_header.U32("conn_count");
    const uint32_t chunk_count = bag_header.U32("chunk_count");
    if (index_pos != 0 && (index_pos < first.end() || index_pos >= file_size_)) {
      Bad(path, first.pos, "the bag header's index position is outside the file");
    }

    std::map<uint32_t, size_t> connection_at;  // id -> index in connections_
    auto define = [&](uint32_t id, const std::string& topic, std::string_view data, uint64_t at) {
      const Fields d(path, at, data);
      BagConnection c;
      c.id = id;
      c.topic = topic;
      c.type = d.String("type");
      c.md5sum = d.String("md5sum");
      const auto it = connection_at.find(id);
      if (it == connection_at.end()) {
        connection_at[id] = connections_.size();
        connections_.push_back(std::move(c));
      } else {
        const BagConnection& old = connections_[it->second];
        if (old.topic != c.topic || old.type != c.type || old.md5sum != c.md5sum) {
          Bad(path, at, "connection " + std::to_string(id) + " is defined twice, differently");
        }
      }
    };

    std::string chunk_bytes;
    bool in_index = false;  // past the chunks: connections and chunk infos only
    for (uint64_t pos = first.end(); pos < file_size_;) {
      const Record r = read_record(pos);
      const Fields f(path, pos, r.header);
      const uint8_t op = f.U8("op");
      if (index_pos != 0 && pos == index_pos) in_index = true;
      if (index_pos != 0 && pos > index_pos && !in_index) {
        Bad(path, pos, "the bag header's index position is not a record's");
      }
      if (op == kChunk) {
        if (in_index) Bad(path, pos, "a chunk after the index");
        const std::string compression = f.String("compression");
        Chunk c;
        c.compression = compression == "none"  ? kNone
                        : compression == "bz2" ? kBz2
                        : compression == "lz4" ? kLz4
                                               : -1;
        if (c.compression < 0) {
          Bad(path, pos,
              "unknown chunk compression '" + EscapeForTerminal(compression.substr(0, 16)) + "'");
        }
        c.size = f.U32("size");
        c.data_pos = r.data_pos;
        c.data_len = r.data_len;
        if (c.size > kMaxBagChunkBytes) {
          Bad(path, pos,
              "a chunk of " + std::to_string(c.size) + " bytes (at most " +
                  std::to_string(kMaxBagChunkBytes) + ")");
        }
        if (chunks_.size() >= UINT32_MAX) Bad(path, pos, "too many chunks");
        LoadChunk(c, pos, &chunk_bytes);
        const uint32_t chunk_index = static_cast<uint32_t>(chunks_.size());
        chunks_.push_back(c);
        chunk_positions_.push_back(pos);
        const std::string_view bytes(chunk_bytes);
        for (size_t at = 0; at < bytes.size();) {
          const InnerRecord in = ReadInnerRecord(path, pos, bytes, at);
          const Fields g(path, pos, in.header);
          const uint8_t inner_op = g.U8("op");
          if (inner_op == kConnection) {
            define(g.U32("conn"), g.String("topic"), bytes.substr(in.data_pos, in.data_len), pos);
          } else if (inner_op == kMessageData) {
            const uint32_t id = g.U32("conn");
            const auto it = connection_at.find(id);
            if (it == connection_at.end()) {
              Bad(path, pos, "a message of connection " + std::to_string(id) + ", never defined");
            }
            const std::string_view time = g.Raw("time", 8);
            BagMessage m;
            m.connection = id;
            m.sec = Le32(reinterpret_cast<const uint8_t*>(time.data()));
            m.nsec = Le32(reinterpret_cast<const uint8_t*>(time.data() + 4));
            m.chunk = chunk_index;
            m.offset = static_cast<uint32_t>(in.data_pos);
            m.size = in.data_len;
            visit(m, connections_[it->second],
                  reinterpret_cast<const uint8_t*>(bytes.data() + in.data_pos), in.data_len);
          } else {
            Bad(path, pos, "a record of op " + std::to_string(inner_op) + " inside a chunk");
          }
          at = in.data_pos + in.data_len;
        }
      } else if (op == kIndexData) {
        if (in_index || chunks_.empty()) Bad(path, pos, "an index record not after a chunk");
        if (f.U32("ver") != 1) Bad(path, pos, "an index record of another version than 1");
        f.U32("conn");
        if (uint64_t{f.U32("count")} * 12 != r.data_len) {
          Bad(path, pos, "an index record whose count does not fit its length");
        }
      } else if (op == kConnection) {
        if (!in_index) Bad(path, pos, "a connection record outside a chunk before the index");
        std::string data(r.data_len, '\0');
        read_at(r.data_pos, data.data(), data.size());
        define(f.U32("conn"), f.String("topic"), data, pos);
      } else if (op == kChunkInfo) {
        if (!in_index) Bad(path, pos, "a chunk info record before the index");
        if (f.U32("ver") != 1) Bad(path, pos, "a chunk info record of another version than 1");
        const uint64_t chunk_pos = f.U64("chunk_pos");
        f.U64("start_time");
        f.U64("end_time");
        if (!std::binary_search(chunk_positions_.begin(), chunk_positions_.end(), chunk_pos)) {
          Bad(path, pos, "a chunk info record names no chunk's position");
        }
        if (uint64_t{f.U32("count")} * 8 != r.data_len) {
          Bad(path, pos, "a chunk info record whose count does not fit its length");
        }
      } else {
        Bad(path, pos, "a record of op " + std::to_string(op) + " where chunks or the index go");
      }
      pos = r.end();
    }
    if (index_pos != 0) {
      if (!in_index) Bad(path, index_pos, "the bag header's index position is not a record's");
      if (chunk_count != chunks_.size() || conn_count != connections_.size()) {
        Bad(path, first.pos,
            "the bag header counts " + std::to_string(chunk_count) + " chunks and " +
                std::to_string(conn_count) + " connections, the file holds " +
                std::to_string(chunks_.size()) + " and " + std::to_string(connections_.size()));
      }
    }
  } catch (...) {
    ::close(fd_);
    fd_ = -1;
    throw;
  }
}

BagReader::~BagReader() {
  if (fd_ >= 0) ::close(fd_);
}

const BagConnection* BagReader::FindConnection(uint32_t id) const {
  for (const BagConnection& c : connections_) {
    if (c.id == id) return &c;
  }
  return nullptr;
}

void BagReader::LoadChunk(const Chunk& c, uint64_t record_pos, std::string* out) const {
  if (c.data_len > kMaxBagChunkBytes) {
    Bad(path_, record_pos,
        "a chunk of " + std::to_string(c.data_len) + " bytes (at most " +
            std::to_string(kMaxBagChunkBytes) + ")");
  }
  std::string data(c.data_len, '\0');
  size_t done = 0;
  while (done < data.size()) {
    const ssize_t got =
        ::pread(fd_, data.data() + done, data.size() - done, static_cast<off_t>(c.data_pos + done));
    if (got < 0 && errno == EINTR) continue;
    if (got < 0) PLACEDB_THROW_IO("cannot read the bag ", path_, ": ", std::strerror(errno));
    if (got == 0) Bad(path_, c.data_pos + done, "the file ends early");
    done += static_cast<size_t>(got);
  }
  if (c.compression == kNone) {
    if (c.size != c.data_len)
      Bad(path_, record_pos, "an uncompressed chunk's size is not its length");
    *out = std::move(data);
    return;
  }
  // lz4 expands at most 255 times; bzip2 has no such bound (the size cap
  // holds it).
  if (c.compression == kLz4 && c.size > uint64_t{c.data_len} * 255 + 64) {
    Bad(path_, record_pos, "an lz4 chunk states more bytes than its data can hold");
  }
  out->assign(c.size, '\0');
  unsigned int got = c.size;
  bool ok = false;
  if (c.compression == kBz2) {
    ok = BZ2_bzBuffToBuffDecompress(out->data(), &got, data.data(), c.data_len, 0, 0) == BZ_OK;
  } else {
    ok = roslz4_buffToBuffDecompress(data.data(), c.data_len, out->data(), &got) == ROSLZ4_OK;
  }
  if (!ok || got != c.size)
    Bad(path_, record_pos, "a compressed chunk does not decompress to its size");
}

std::string BagReader::ReadMessage(const BagMessage& m) const {
  if (m.chunk >= chunks_.size()) {
    PLACEDB_THROW_INVALID("the bag ", path_, " has no chunk ", m.chunk);
  }
  std::lock_guard<std::mutex> lock(cache_mutex_);
  if (cached_chunk_ != static_cast<int64_t>(m.chunk)) {
    cached_chunk_ = -1;
    LoadChunk(chunks_[m.chunk], chunk_positions_[m.chunk], &cached_);
    cached_chunk_ = m.chunk;
  }
  if (m.offset > cached_.size() || m.size > cached_.size() - m.offset) {
    Bad(path_, chunk_positions_[m.chunk],
        "a chunk changed since it was read: it no longer holds its message");
  }
  return cached_.substr(m.offset, m.size);
}

}  // namespace placedb
