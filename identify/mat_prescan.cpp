#include "identify/mat_prescan.h"

#include <zlib.h>

#include <algorithm>
#include <cstdint>
#include <fstream>
#include <iterator>
#include <utility>
#include <vector>

#include "millkit/io/input_error.h"
#include "millkit/io/input_file.h"

namespace millkit::identify {
namespace {

constexpr std::size_t kHeaderBytes = 128;
constexpr int kMaxDepth = 32;
// zlib's deflate expands nothing by more than 1032 to 1 (RFC 1951's longest match per bit).
constexpr std::uint64_t kMaxInflationRatio = 1032;

// Data types (MAT-file format, "Data Element" table).
enum : std::uint32_t {
  kInt8 = 1,
  kUint8 = 2,
  kInt16 = 3,
  kUint16 = 4,
  kInt32 = 5,
  kUint32 = 6,
  kSingle = 7,
  kDouble = 9,
  kInt64 = 12,
  kUint64 = 13,
  kMatrix = 14,
  kCompressed = 15,
  kUtf8 = 16,
  kUtf16 = 17,
  kUtf32 = 18,
};

// Array classes (the low byte of the array flags).
enum : std::uint32_t {
  kCellClass = 1,
  kStructClass = 2,
  kObjectClass = 3,
  kCharClass = 4,
  kSparseClass = 5,
  kFirstNumericClass = 6,  // double … uint64
  kLastNumericClass = 15,
  kFunctionClass = 16,
  kOpaqueClass = 17,
};

std::size_t TypeBytes(std::uint32_t type) {
  switch (type) {
    case kInt8:
    case kUint8:
    case kUtf8:
      return 1;
    case kInt16:
    case kUint16:
    case kUtf16:
      return 2;
    case kInt32:
    case kUint32:
    case kSingle:
    case kUtf32:
      return 4;
    case kDouble:
    case kInt64:
    case kUint64:
      return 8;
    default:
      return 0;
  }
}

std::size_t RoundUp8(std::size_t n) { return (n + 7) & ~std::size_t{7}; }

struct Tag {
  std::uint32_t type = 0;
  std::size_t size = 0;  // bytes of data
  std::size_t data = 0;  // offset of the data
  std::size_t next = 0;  // offset of the next element
  bool small = false;    // size and type in one word, the data in the tag's second word
};

// Reads tags and words of one byte range (the file, or one inflated variable) and names places
// in it when a rule is broken.
class Walker {
 public:
  Walker(std::string_view bytes, bool swap, std::string source, std::size_t compressed_at,
         bool compressed)
      : bytes_(bytes),
        swap_(swap),
        source_(std::move(source)),
        compressed_at_(compressed_at),
        compressed_(compressed) {}

  [[noreturn]] void Fail(std::size_t at, const std::string& rule) const {
    std::string where = "byte " + std::to_string(at);
    if (compressed_) {
      where += " of the variable compressed at byte " + std::to_string(compressed_at_);
    }
    throw InputError(source_ + ": damaged MAT file: " + rule + " (" + where + ")");
  }

  std::uint32_t Word(std::size_t at) const {
    std::uint32_t w = 0;
    for (int i = 0; i < 4; ++i) {
      const auto byte = static_cast<std::uint32_t>(static_cast<unsigned char>(bytes_[at + i]));
      w |= swap_ ? byte << (8 * (3 - i)) : byte << (8 * i);
    }
    return w;
  }

  // The element whose tag starts at `at`, inside a container that ends at `end`. Elements inside
  // a variable are padded to 8 bytes; top-level ones are not.
  Tag Read(std::size_t at, std::size_t end, bool padded) const {
    if (end < at || end - at < 8) Fail(at, "a data element's 8-byte tag runs past its container");
    Tag tag;
    const std::uint32_t first = Word(at);
    if ((first >> 16) != 0) {  // small data element: size and type in one word, data in 4 bytes
      tag.type = first & 0xFFFF;
      tag.size = first >> 16;
      if (tag.size > 4) Fail(at, "a small data element declares more than 4 bytes");
      tag.data = at + 4;
      tag.next = at + 8;
      tag.small = true;
      return tag;
    }
    tag.type = first;
    tag.size = Word(at + 4);
    tag.data = at + 8;
    if (tag.size > end - tag.data) {
      Fail(at, "a data element declares " + std::to_string(tag.size) +
                   " bytes, but its container has " + std::to_string(end - tag.data) + " left");
    }
    tag.next = tag.data + tag.size;
    if (padded) tag.next = std::min(RoundUp8(tag.next), end);
    return tag;
  }

  // The product of a dimensions element's values, capped at 2^48 (no file holds as many; the cap
  // keeps the product from overflowing).
  std::uint64_t Elements(const Tag& dims) const {
    std::uint64_t elements = 1;
    for (std::size_t d = 0; d < dims.size; d += 4) {
      const auto dim = static_cast<std::int32_t>(Word(dims.data + d));
      if (dim < 0) Fail(dims.data + d, "a negative dimension");
      if (dim == 0) return 0;
      elements = std::min<std::uint64_t>(elements * static_cast<std::uint64_t>(dim),
                                         std::uint64_t{1} << 48);
    }
    return elements;
  }

  // The contents of a miMATRIX element, [at, end).
  void Matrix(std::size_t at, std::size_t end, int depth) const {
    if (at == end) return;  // an empty placeholder (a struct field never set)
    if (depth > kMaxDepth) Fail(at, "variables nested deeper than " + std::to_string(kMaxDepth));
    const Tag flags = Read(at, end, true);
    if (flags.type != kUint32 || flags.size != 8) {
      Fail(at, "a variable's array flags must be 8 bytes of type miUINT32");
    }
    const std::uint32_t array_class = Word(flags.data) & 0xFF;
    const bool complex = (Word(flags.data) & 0x800) != 0;
    if (array_class < kCellClass || array_class > kOpaqueClass) {
      Fail(flags.data, "unknown array class " + std::to_string(array_class));
    }
    const Tag dims = Read(flags.next, end, true);
    // libmatio reads a full miINT32 dimensions element as size / 4 values (padded to 8 bytes
    // when their count is odd) and then the name where they end: whole values keep its reading
    // in step with the element's end, where this check reads on.
    const bool int32_dims = dims.type == kInt32 && !dims.small;
    if (int32_dims && dims.size % 4 != 0) {
      Fail(flags.next, "a variable's dimensions are " + std::to_string(dims.size) +
                           " bytes, not whole miINT32 values");
    }
    const bool has_dims = int32_dims && dims.size >= 8;
    const std::uint64_t elements = has_dims ? Elements(dims) : 0;
    if (array_class == kOpaqueClass) {
      // Laid out otherwise (an object has no dimensions; what follows its flags is its name):
      // libmatio still takes a full miINT32 element there for dimensions, and reads a name tag
      // where they end, or else right after that element's tag, allocating the length it
      // declares. Every element's size is held to the container.
      if (has_dims && elements > end - dims.next) {
        Fail(flags.next, "the dimensions claim " + std::to_string(elements) +
                             " elements, more than the " + std::to_string(end - dims.next) +
                             " bytes left");
      }
      const std::size_t name_at = int32_dims || dims.small ? dims.next : dims.data;
      if (name_at != dims.next) {
        if (end - name_at < 8) Fail(name_at, "an object's name tag runs past its container");
        if (Word(name_at) == kInt8 && Word(name_at + 4) > end - name_at - 8) {
          Fail(name_at, "an object's name declares " + std::to_string(Word(name_at + 4)) +
                            " bytes, more than the " + std::to_string(end - name_at - 8) +
                            " bytes left");
        }
      }
      SkipElements(dims.next, end);
      return;
    }
    if (!has_dims) Fail(flags.next, "a variable's dimensions must be two or more miINT32");
    const Tag name = Read(dims.next, end, true);
    if (name.type != kInt8) Fail(dims.next, "a variable's name must be of type miINT8");
    std::size_t cursor = name.next;
    // `count` elements of at least `least` bytes each must fit in what is left.
    const auto fits = [&](std::uint64_t count, std::uint64_t least, const std::string& what) {
      if (count > (end - cursor) / least) {
        Fail(cursor, "the dimensions claim " + std::to_string(count) + " " + what +
                         ", more than the " + std::to_string(end - cursor) +
                         " bytes left can hold");
      }
    };
    const auto numeric = [&](const char* part) {
      const Tag values = Read(cursor, end, true);
      const std::size_t bytes = TypeBytes(values.type);
      if (bytes == 0) {
        Fail(cursor, std::string("the ") + part + " part has the non-numeric type " +
                         std::to_string(values.type));
      }
      if (elements > values.size / bytes) {
        Fail(cursor, "the dimensions claim " + std::to_string(elements) + " elements, the " + part +
                         " part holds " + std::to_string(values.size / bytes));
      }
      cursor = values.next;
    };
    if (array_class == kCharClass ||
        (array_class >= kFirstNumericClass && array_class <= kLastNumericClass)) {
      if (elements == 0 && cursor == end) return;  // an empty array may carry no data element
      numeric("real");
      if (complex) numeric("imaginary");
      return;
    }
    if (array_class == kFunctionClass) {
      // A function handle: where an uncompressed one's name ends, libmatio reads as many
      // variables as its dimensions claim, each as a top-level one (a pointer each first); a
      // compressed one it does not read on.
      if (!compressed_) {
        fits(elements, 8, "function handle parts");
        for (std::uint64_t i = 0; i < elements; ++i) cursor = Child(cursor, end, depth);
      }
      SkipElements(cursor, end);
      return;
    }
    if (array_class == kSparseClass) {
      // Its index and value arrays: every element's size held to the container, and the number
      // of non-zeros (array flags, second word) to the bytes left.
      const std::uint64_t nonzeros = Word(flags.data + 4);
      if (nonzeros > end - cursor) {
        Fail(flags.data + 4, "a sparse matrix claims " + std::to_string(nonzeros) +
                                 " non-zeros, more than the " + std::to_string(end - cursor) +
                                 " bytes left");
      }
      // Row indices, column starts, real and imaginary values: numeric, each held to the
      // container (libmatio reads an element of an unknown type as another tag).
      for (int part = 0; part < 2 || end - cursor >= 8; ++part) {
        if (end - cursor < 8) Fail(cursor, "a sparse matrix needs row indices and column starts");
        const Tag values = Read(cursor, end, true);
        if (TypeBytes(values.type) == 0) {
          Fail(cursor, "a sparse matrix's indices and values must be numeric (type " +
                           std::to_string(values.type) + ")");
        }
        cursor = values.next;
      }
      return;
    }
    if (array_class == kCellClass) {
      fits(elements, 8, "cells");
      for (std::uint64_t i = 0; i < elements; ++i) cursor = Child(cursor, end, depth);
      return;
    }
    // A struct, or an object (a struct with a class name).
    if (array_class == kObjectClass) {
      const Tag class_name = Read(cursor, end, true);
      if (class_name.type != kInt8) Fail(cursor, "an object's class name must be of type miINT8");
      cursor = class_name.next;
    }
    const Tag length = Read(cursor, end, true);
    if (length.type != kInt32 || length.size != 4) {
      Fail(cursor, "a struct's field name length must be one miINT32");
    }
    const std::uint32_t name_length = Word(length.data);
    const Tag names = Read(length.next, end, true);
    if (names.type != kInt8) Fail(length.next, "a struct's field names must be of type miINT8");
    if (name_length == 0 ? names.size != 0 : names.size % name_length != 0) {
      Fail(length.next, "a struct's field names are not whole names of " +
                            std::to_string(name_length) + " bytes");
    }
    const std::uint64_t fields = name_length == 0 ? 0 : names.size / name_length;
    cursor = names.next;
    if (fields == 0) return;
    const std::uint64_t count =
        elements > (std::uint64_t{1} << 48) / fields ? (std::uint64_t{1} << 48) : elements * fields;
    fits(count, 8, "struct fields");
    for (std::uint64_t i = 0; i < count; ++i) cursor = Child(cursor, end, depth);
  }

 private:
  // Every element from `at` to `end`, only held to the container.
  void SkipElements(std::size_t at, std::size_t end) const {
    while (end - at >= 8) at = Read(at, end, true).next;
  }

  // A cell, a struct field or a function handle's part: a miMATRIX element; returns the offset
  // after it.
  std::size_t Child(std::size_t at, std::size_t end, int depth) const {
    const Tag child = Read(at, end, true);
    if (child.type != kMatrix)
      Fail(at, "a cell, struct field or function handle part must be a miMATRIX element");
    Matrix(child.data, child.data + child.size, depth + 1);
    return child.next;
  }

  std::string_view bytes_;
  bool swap_;
  std::string source_;
  std::size_t compressed_at_;
  bool compressed_;
};

struct Inflater {
  z_stream stream{};
  bool open = false;
  ~Inflater() {
    if (open) inflateEnd(&stream);
  }
};

// Inflates up to `size` bytes into `out`; returns how many came out, with `why` set when the
// stream is damaged.
std::size_t Inflate(Inflater* z, char* out, std::size_t size, std::string* why) {
  std::size_t produced = 0;
  while (produced < size) {
    const std::size_t chunk = std::min<std::size_t>(size - produced, std::size_t{1} << 30);
    z->stream.next_out = reinterpret_cast<Bytef*>(out + produced);
    z->stream.avail_out = static_cast<uInt>(chunk);
    const int status = inflate(&z->stream, Z_NO_FLUSH);
    produced += chunk - z->stream.avail_out;
    if (status == Z_STREAM_END) break;
    if (status != Z_OK) {
      *why = z->stream.msg != nullptr ? z->stream.msg : "error " + std::to_string(status);
      break;
    }
    if (z->stream.avail_in == 0) break;  // the stream ends before `size` bytes
  }
  return produced;
}

// A top-level miCOMPRESSED element: its stream inflates to one miMATRIX element, which is
// checked like an uncompressed one.
void CheckCompressed(std::string_view file, const Tag& tag, std::size_t at, bool swap,
                     const std::string& source) {
  const Walker outer(file, swap, source, at, false);
  Inflater z;
  z.stream.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(file.data() + tag.data));
  z.stream.avail_in = static_cast<uInt>(tag.size);  // from a 32-bit tag
  if (inflateInit(&z.stream) != Z_OK) outer.Fail(at, "zlib could not start");
  z.open = true;
  std::vector<char> whole(8);
  std::string why;
  if (Inflate(&z, whole.data(), 8, &why) < 8) {
    outer.Fail(at, "a compressed variable's zlib stream is damaged" +
                       (why.empty() ? std::string() : " (zlib: " + why + ")"));
  }
  const Walker first(std::string_view(whole.data(), whole.size()), swap, source, at, true);
  const std::uint32_t type = first.Word(0);
  const std::uint64_t size = first.Word(4);
  if (type != kMatrix) first.Fail(0, "a compressed element must hold a miMATRIX variable");
  if (size > kMaxInflatedVariableBytes || size > kMaxInflationRatio * tag.size) {
    first.Fail(0, "the variable declares " + std::to_string(size) + " bytes, more than its " +
                      std::to_string(tag.size) +
                      " compressed bytes can hold (zlib expands at most " +
                      std::to_string(kMaxInflationRatio) + " times; at most " +
                      std::to_string(kMaxInflatedVariableBytes) + " bytes are read)");
  }
  whole.resize(8 + static_cast<std::size_t>(size));
  const std::size_t produced = Inflate(&z, whole.data() + 8, static_cast<std::size_t>(size), &why);
  if (produced < size) {
    first.Fail(8, "the variable's zlib stream ends or breaks after " + std::to_string(produced) +
                      " of its " + std::to_string(size) + " bytes" +
                      (why.empty() ? std::string() : " (zlib: " + why + ")"));
  }
  const Walker inner(std::string_view(whole.data(), whole.size()), swap, source, at, true);
  inner.Matrix(8, whole.size(), 0);
}

MatVersion CheckHeader(std::string_view bytes, const std::string& source, bool* swap) {
  const auto refuse = [&](const std::string& why) {
    throw InputError(source + ": not a MAT v5 or v7.3 file: " + why);
  };
  if (bytes.size() < kHeaderBytes) refuse("shorter than the 128-byte MAT header");
  const std::string_view endian = bytes.substr(126, 2);
  if (endian == "IM") {
    *swap = false;
  } else if (endian == "MI") {
    *swap = true;
  } else {
    refuse("no endian indicator 'IM' or 'MI' at byte 126");
  }
  const auto low = static_cast<unsigned>(static_cast<unsigned char>(bytes[124]));
  const auto high = static_cast<unsigned>(static_cast<unsigned char>(bytes[125]));
  const unsigned version = *swap ? (low << 8 | high) : (high << 8 | low);
  if (version == 0x0100) return MatVersion::kV5;
  if (version == 0x0200) return MatVersion::kV73;
  throw InputError(source + ": not a MAT v5 or v7.3 file: version " + std::to_string(version) +
                   " at byte 124 (256: v5, 512: v7.3)");
}

}  // namespace

MatVersion CheckMatBytes(std::string_view bytes, const std::string& source) {
  bool swap = false;
  const MatVersion version = CheckHeader(bytes, source, &swap);
  if (version == MatVersion::kV73) return version;  // HDF5: read by libmatio through libhdf5
  const Walker file(bytes, swap, source, 0, false);
  std::size_t at = kHeaderBytes;
  // Fewer than 8 bytes at the end are no element; libmatio stops there too.
  while (bytes.size() - at >= 8) {
    const Tag tag = file.Read(at, bytes.size(), false);
    if (tag.type == kMatrix) {
      file.Matrix(tag.data, tag.data + tag.size, 0);
    } else if (tag.type == kCompressed) {
      CheckCompressed(bytes, tag, at, swap, source);
    }
    at = tag.next;
  }
  return version;
}

MatVersion CheckMatFile(const std::filesystem::path& path, const std::string& source) {
  CheckInputFile(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(source + ": cannot open it");
  std::string bytes(kHeaderBytes, '\0');
  in.read(bytes.data(), static_cast<std::streamsize>(kHeaderBytes));
  bytes.resize(static_cast<std::size_t>(in.gcount()));
  bool swap = false;
  if (CheckHeader(bytes, source, &swap) == MatVersion::kV73) return MatVersion::kV73;
  bytes.append(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  return CheckMatBytes(bytes, source);
}

}  // namespace millkit::identify
