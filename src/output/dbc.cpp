#include "cndt/output/dbc.hpp"

#include <fmt/format.h>

#include <cerrno>
#include <charconv>
#include <cstring>
#include <fstream>
#include <regex>
#include <sstream>

namespace cndt::output {
namespace {

// The bit positions of a signal, most significant first, as frame bit numbers (byte * 8 + bit,
// bit 0 the LSB of its byte). Intel signals run upwards from the start bit (their LSB); Motorola
// signals start at their MSB and run down a byte, then on at bit 7 of the next byte.
template <class F>
bool for_each_bit_msb_first(const DbcSignal& s, unsigned frame_bits, F&& f) {
  if (s.little_endian) {
    if (s.start + s.length > frame_bits) return false;
    for (unsigned i = s.length; i-- > 0;) f(s.start + i);
    return true;
  }
  unsigned pos = s.start;
  for (unsigned i = 0; i < s.length; ++i) {
    if (pos >= frame_bits) return false;
    f(pos);
    if (i + 1 == s.length) break;
    if (pos % 8 == 0) {
      pos += 15;
    } else {
      --pos;
    }
  }
  return true;
}

bool parse_double(const std::string& s, double& out) {
  const char* b = s.data();
  const char* e = b + s.size();
  while (b < e && *b == ' ') ++b;
  while (e > b && e[-1] == ' ') --e;
  const auto r = std::from_chars(b, e, out);
  return r.ec == std::errc() && r.ptr == e;
}

core::Error error_at(const std::string& source, int line, const std::string& what) {
  return {core::kExitDataError, fmt::format("{}:{}: {}", source, line, what)};
}

std::string unquote_all(const std::string& rest) {
  // The first "..." of a CM_ statement, with \" kept as a quote.
  const auto q = rest.find('"');
  if (q == std::string::npos) return {};
  std::string out;
  for (std::size_t i = q + 1; i < rest.size(); ++i) {
    if (rest[i] == '\\' && i + 1 < rest.size()) {
      out += rest[++i];
    } else if (rest[i] == '"') {
      break;
    } else {
      out += rest[i];
    }
  }
  return out;
}

// Quotes in a line outside escapes: a statement is complete when they balance.
bool quotes_balanced(const std::string& s) {
  bool in = false;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (in && s[i] == '\\') {
      ++i;
    } else if (s[i] == '"') {
      in = !in;
    }
  }
  return !in;
}

}  // namespace

std::int64_t DbcSignal::raw(std::span<const std::uint8_t> data) const noexcept {
  std::uint64_t v = 0;
  const auto bits = static_cast<unsigned>(data.size() * 8);
  for_each_bit_msb_first(*this, bits, [&](unsigned pos) {
    v = (v << 1) | ((static_cast<unsigned>(data[pos / 8]) >> (pos % 8)) & 1u);
  });
  if (is_signed && length < 64 && ((v >> (length - 1)) & 1u) != 0) v |= ~0ull << length;
  return static_cast<std::int64_t>(v);
}

double DbcSignal::physical(std::span<const std::uint8_t> data) const noexcept {
  const std::int64_t r = raw(data);
  const double rv =
      is_signed ? static_cast<double>(r) : static_cast<double>(static_cast<std::uint64_t>(r));
  return rv * factor + offset;
}

const DbcSignal* DbcMessage::signal(std::string_view n) const noexcept {
  for (const auto& s : signals) {
    if (s.name == n) return &s;
  }
  return nullptr;
}

const DbcMessage* DbcDatabase::message(std::uint32_t id, bool extended) const noexcept {
  for (const auto& m : messages) {
    if (m.id == id && m.extended == extended) return &m;
  }
  return nullptr;
}

const DbcMessage* DbcDatabase::message(std::string_view n) const noexcept {
  for (const auto& m : messages) {
    if (m.name == n) return &m;
  }
  return nullptr;
}

core::Result<DbcDatabase> parse_dbc(std::string_view text, const std::string& source) {
  static const std::regex kMessage(R"(^BO_\s+(\d+)\s+(\w+)\s*:\s*(\d+)\s+(\w+)\s*$)");
  static const std::regex kSignal(
      R"(^SG_\s+(\w+)\s*(M|m\d+)?\s*:\s*(\d+)\|(\d+)@([01])([+-])\s*\(([^,()]+),([^,()]+)\)\s*)"
      R"re(\[([^|\]]+)\|([^|\]]+)\]\s*"([^"]*)"\s*(.*)$)re");
  static const std::regex kValues(R"(^VAL_\s+(\d+)\s+(\w+)\s+(.*);\s*$)");
  static const std::regex kValuePair(R"re((-?\d+)\s+"([^"]*)")re");
  static const std::regex kSignalComment(R"(^CM_\s+SG_\s+(\d+)\s+(\w+)\s+")");
  static const std::regex kMessageComment(R"(^CM_\s+BO_\s+(\d+)\s+")");
  static const std::regex kValType(R"(^SIG_VALTYPE_\s+(\d+)\s+(\w+)\s*:?\s*(\d+)\s*;)");

  DbcDatabase db;
  std::istringstream in{std::string(text)};
  std::string line;
  int lineno = 0;
  bool saw_version = false;
  const auto find_signal = [&](std::uint32_t dbc_id, const std::string& name) -> DbcSignal* {
    const bool ext = (dbc_id & 0x80000000u) != 0;
    for (auto& m : db.messages) {
      if (m.id == (dbc_id & 0x1FFFFFFFu) && m.extended == ext) {
        for (auto& s : m.signals) {
          if (s.name == name) return &s;
        }
      }
    }
    return nullptr;
  };
  const auto find_message = [&](std::uint32_t dbc_id) -> DbcMessage* {
    const bool ext = (dbc_id & 0x80000000u) != 0;
    for (auto& m : db.messages) {
      if (m.id == (dbc_id & 0x1FFFFFFFu) && m.extended == ext) return &m;
    }
    return nullptr;
  };
  while (std::getline(in, line)) {
    ++lineno;
    const int first_line = lineno;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const auto b = line.find_first_not_of(" \t");
    if (b == std::string::npos) continue;
    std::string stmt = line.substr(b);
    // Statements with strings may span lines (comments); join until the quotes balance.
    while (!quotes_balanced(stmt)) {
      std::string more;
      if (!std::getline(in, more)) {
        return error_at(source, first_line, "unterminated string");
      }
      ++lineno;
      if (!more.empty() && more.back() == '\r') more.pop_back();
      stmt += '\n';
      stmt += more;
    }
    std::smatch m;
    if (stmt.rfind("VERSION", 0) == 0) {
      saw_version = true;
    } else if (stmt.rfind("BO_ ", 0) == 0) {
      if (!std::regex_match(stmt, m, kMessage)) {
        return error_at(source, first_line,
                        "malformed message: expected 'BO_ <id> <name>: <bytes> <transmitter>'");
      }
      DbcMessage msg;
      const unsigned long long id = std::stoull(m[1]);
      if (id > 0xFFFFFFFFull) return error_at(source, first_line, "message id out of range");
      msg.extended = (id & 0x80000000ull) != 0;
      msg.id = static_cast<std::uint32_t>(id & 0x1FFFFFFFull);
      if (!msg.extended && msg.id > 0x7FF) {
        return error_at(
            source, first_line,
            fmt::format("standard id {:#x} above 0x7FF (set bit 31 for extended)", msg.id));
      }
      msg.name = m[2];
      msg.length = static_cast<unsigned>(std::stoul(m[3]));
      if (msg.length > 64) {
        return error_at(
            source, first_line,
            fmt::format("message '{}' is {} bytes long (at most 64)", msg.name, msg.length));
      }
      msg.transmitter = m[4];
      msg.line = first_line;
      db.messages.push_back(std::move(msg));
    } else if (stmt.rfind("SG_ ", 0) == 0) {
      if (db.messages.empty()) {
        return error_at(source, first_line, "signal before any message (BO_)");
      }
      if (!std::regex_match(stmt, m, kSignal)) {
        return error_at(source, first_line,
                        "malformed signal: expected 'SG_ <name> : <start>|<length>@<0|1><+|-> "
                        "(<factor>,<offset>) [<min>|<max>] \"<unit>\" <receivers>'");
      }
      DbcSignal s;
      s.name = m[1];
      const std::string mux = m[2];
      if (mux == "M") {
        s.is_multiplexer = true;
      } else if (!mux.empty()) {
        s.multiplexed_by = std::stoi(mux.substr(1));
      }
      s.start = static_cast<unsigned>(std::stoul(m[3]));
      s.length = static_cast<unsigned>(std::stoul(m[4]));
      s.little_endian = m[5] == "1";
      s.is_signed = m[6] == "-";
      if (!parse_double(m[7], s.factor) || !parse_double(m[8], s.offset) ||
          !parse_double(m[9], s.minimum) || !parse_double(m[10], s.maximum)) {
        return error_at(source, first_line,
                        fmt::format("signal '{}': factor, offset, minimum and maximum must be "
                                    "numbers",
                                    s.name));
      }
      s.unit = m[11];
      s.line = first_line;
      DbcMessage& msg = db.messages.back();
      if (s.length == 0 || s.length > 64) {
        return error_at(source, first_line,
                        fmt::format("signal '{}': length {} (1..64 bits)", s.name, s.length));
      }
      if (s.factor == 0.0) {
        return error_at(source, first_line, fmt::format("signal '{}': factor 0", s.name));
      }
      if (!for_each_bit_msb_first(s, msg.length * 8, [](unsigned) {})) {
        return error_at(
            source, first_line,
            fmt::format("signal '{}' ({}|{}@{}) does not fit in the {}-byte message "
                        "'{}'",
                        s.name, s.start, s.length, s.little_endian ? 1 : 0, msg.length, msg.name));
      }
      if (msg.signal(s.name) != nullptr) {
        return error_at(source, first_line,
                        fmt::format("signal '{}' declared twice in '{}'", s.name, msg.name));
      }
      msg.signals.push_back(std::move(s));
    } else if (stmt.rfind("VAL_ ", 0) == 0) {
      if (!std::regex_match(stmt, m, kValues)) {
        return error_at(source, first_line,
                        "malformed value table: expected 'VAL_ <id> <signal> <raw> \"<text>\" "
                        "... ;'");
      }
      DbcSignal* s = find_signal(static_cast<std::uint32_t>(std::stoull(m[1])), m[2]);
      if (s == nullptr) {
        return error_at(source, first_line,
                        fmt::format("value table for unknown signal '{}' of message {}", m[2].str(),
                                    m[1].str()));
      }
      const std::string pairs = m[3];
      for (std::sregex_iterator it(pairs.begin(), pairs.end(), kValuePair), end; it != end; ++it) {
        s->values[std::stoll((*it)[1])] = (*it)[2];
      }
    } else if (std::regex_search(stmt, m, kSignalComment)) {
      if (DbcSignal* s = find_signal(static_cast<std::uint32_t>(std::stoull(m[1])), m[2])) {
        s->comment = unquote_all(stmt);
      }
    } else if (std::regex_search(stmt, m, kMessageComment)) {
      if (DbcMessage* msg = find_message(static_cast<std::uint32_t>(std::stoull(m[1])))) {
        msg->comment = unquote_all(stmt);
      }
    } else if (std::regex_search(stmt, m, kValType)) {
      if (m[3] != "0") {
        return error_at(source, first_line,
                        fmt::format("signal '{}': floating-point signals (SIG_VALTYPE_) are not "
                                    "supported",
                                    m[2].str()));
      }
    }
    // NS_ symbol lists, BS_, BU_, CM_ of nodes, BA_DEF_/BA_ attributes: layout-neutral.
  }
  if (!saw_version && db.messages.empty()) {
    return core::Error{core::kExitDataError,
                       fmt::format("{}: not a DBC file (no VERSION and no BO_ message)", source)};
  }
  return db;
}

core::Result<DbcDatabase> load_dbc(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) {
    return core::Error{core::kExitNoInput,
                       fmt::format("cannot open DBC file '{}': {}", path, std::strerror(errno))};
  }
  std::ostringstream ss;
  ss << f.rdbuf();
  return parse_dbc(ss.str(), path);
}

}  // namespace cndt::output
