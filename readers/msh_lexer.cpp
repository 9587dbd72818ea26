// MSH lexer: tokens and binary values out of the whole file in memory, each
// read checked against the end of the buffer (see msh_reader.hpp).
#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>

#include "msh_reader.hpp"

namespace dicer::msh {

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f'; }

std::string_view trim(std::string_view s) {
  while (!s.empty() && is_space(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
  return s;
}

std::string shown(std::string_view s) {
  std::string out;
  for (char c : s.substr(0, 40)) out += (c >= 32 && c < 127) ? c : '?';
  if (s.size() > 40) out += "...";
  return out;
}

// ---- messages -----------------------------------------------------------------

std::size_t Lexer::line_of(std::size_t at) const {
  return 1 + static_cast<std::size_t>(std::count(data_.begin(), data_.begin() + static_cast<std::ptrdiff_t>(at), '\n'));
}

std::string Lexer::location() const {
  return in_binary_ ? "byte offset " + std::to_string(tok_) : "line " + std::to_string(line_of(tok_));
}

void Lexer::fail(const std::string& what, ErrorKind kind) const {
  throw Error(kind, path_ + ": " + location() + ": " + (section_.empty() ? "" : section_ + ": ") + what);
}

void Lexer::eof(const std::string& detail) {
  if (detail.empty()) tok_ = data_.size();
  std::string s = path_ + ": " + location() + ": unexpected end of file";
  if (!section_.empty()) s += " in " + section_;
  if (!detail.empty()) s += ": " + detail;
  throw Error(ErrorKind::BadInput, s);
}

void Lexer::too_many(const std::string& what, std::uint64_t n) {
  eof(what + " " + std::to_string(n) + " needs more than the " + std::to_string(remaining()) + " bytes left");
}

// ---- ASCII --------------------------------------------------------------------

void Lexer::skip_space() {
  while (pos_ < data_.size() && is_space(data_[pos_])) ++pos_;
}

std::string_view Lexer::token() {
  skip_space();
  if (pos_ >= data_.size()) eof();
  tok_ = pos_;
  while (pos_ < data_.size() && !is_space(data_[pos_])) ++pos_;
  return std::string_view(data_).substr(tok_, pos_ - tok_);
}

std::string_view Lexer::rest_of_line() {
  const std::size_t start = pos_;
  std::size_t end = data_.find('\n', pos_);
  if (end == std::string::npos) end = data_.size();
  pos_ = std::min(end + 1, data_.size());
  return std::string_view(data_).substr(start, end - start);
}

std::string Lexer::header_line() {
  skip_space();
  tok_ = pos_;
  return std::string(trim(rest_of_line()));
}

Id Lexer::integer(const std::string& what, Id lo, Id hi) {
  std::string_view t = token();
  if (t.size() > 1 && t[0] == '+') t.remove_prefix(1);
  Id v = 0;
  auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
  if (ec != std::errc() || end != t.data() + t.size())
    fail("expected " + what + " (an integer), found '" + shown(t) + "'");
  if (v < lo || v > hi) fail(what + " " + std::to_string(v) + " is out of range");
  return v;
}

std::size_t Lexer::count(const std::string& what, std::size_t tokens_each) {
  const Id n = integer(what, 0);
  if (static_cast<std::uint64_t>(n) > (remaining() + 1) / (2 * tokens_each)) too_many(what, static_cast<std::uint64_t>(n));
  return static_cast<std::size_t>(n);
}

double Lexer::real(const std::string& what) {
  std::string_view t = token();
  if (t.size() > 1 && t[0] == '+') t.remove_prefix(1);
  double v = 0;
  auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
  const bool out_of_range = ec == std::errc::result_out_of_range;
  if ((ec != std::errc() && !out_of_range) || end != t.data() + t.size())
    fail("expected " + what + " (a number), found '" + shown(t) + "'");
  if (out_of_range) {  // underflow (negative exponent) reads as 0, overflow as inf (refused later)
    const std::size_t e = t.find_first_of("eE");
    const bool underflow = e != std::string_view::npos && e + 1 < t.size() && t[e + 1] == '-';
    v = underflow ? 0.0 : std::numeric_limits<double>::infinity();
  }
  return v;
}

void Lexer::expect_line(const std::string& want) {
  skip_space();
  if (pos_ >= data_.size()) eof();
  const std::string line = header_line();
  if (line != want) fail("expected " + want + ", found '" + shown(line) + "'");
}

void Lexer::start_binary_data() {
  while (pos_ < data_.size() && (data_[pos_] == ' ' || data_[pos_] == '\r')) ++pos_;
  if (pos_ >= data_.size()) eof();
  if (data_[pos_] != '\n') {
    tok_ = pos_;
    fail("expected a line end before the binary data");
  }
  ++pos_;
  in_binary_ = true;
}

void Lexer::skip_to_end_line(const std::string& name) {
  const std::string marker = "\n$End" + name;
  std::size_t from = pos_ > 0 ? pos_ - 1 : 0;
  for (;;) {
    const std::size_t at = data_.find(marker, from);
    if (at == std::string::npos) eof("no $End" + name + " line");
    const std::size_t after = at + marker.size();
    if (after == data_.size() || is_space(data_[after])) {
      pos_ = after;
      rest_of_line();
      return;
    }
    from = at + 1;
  }
}

// ---- binary -------------------------------------------------------------------

std::size_t Lexer::bin_count(const std::string& what, std::size_t bytes_each) {
  const std::uint64_t n = bin<std::uint64_t>();
  if (n > remaining() / bytes_each) too_many(what, n);
  return static_cast<std::size_t>(n);
}

Id Lexer::bin_tag(const std::string& what) {
  const std::uint64_t v = bin<std::uint64_t>();
  if (v == 0 || v > static_cast<std::uint64_t>(kMaxId)) fail(what + " " + std::to_string(v) + " is out of range");
  return static_cast<Id>(v);
}

std::int32_t Lexer::bin_int(const std::string& what, Id lo, Id hi) {
  const std::int32_t v = bin<std::int32_t>();
  if (v < lo || v > hi) fail(what + " " + std::to_string(v) + " is out of range");
  return v;
}

void Lexer::skip_bytes(std::uint64_t n) {
  if (n > remaining()) eof();
  pos_ += static_cast<std::size_t>(n);
}

}  // namespace dicer::msh
