// Bit toggles per VCD identifier, counted from VCD text (the power flow's level "signals",
// docs/power.md): the one counter of sim/power_harness.cpp (a VCD file, pw_vcd_count) and of
// sim/rtunit_rtl_harness.cpp (the text streamed straight from Verilator's VCD writer, no file).
//
// A toggle is a bit whose value differs from the identifier's previous value; an identifier's
// first value (its $dumpvars entry) counts nothing. Vectors compare right-aligned, missing
// leading digits are 0, x and z count as 0. Verilator gives a net one identifier however many
// scopes it appears in, so counting per identifier counts each net once. The declarations
// (everything up to $enddefinitions) are kept as text: the driver reads the nets' names there.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

namespace rf_toggles {

class Counter {
 public:
  // Feed the next `n` bytes of VCD text (lines may be split between calls).
  void feed(const char* p, size_t n) {
    size_t start = 0;
    for (size_t i = 0; i < n; i++) {
      if (p[i] != '\n') continue;
      if (partial_.empty()) {
        line(p + start, i - start);
      } else {
        partial_.append(p + start, i - start);
        line(partial_.data(), partial_.size());
        partial_.clear();
      }
      start = i + 1;
    }
    partial_.append(p + start, n - start);
  }

  // The last line, if the text did not end with a newline.
  void finish() {
    if (!partial_.empty()) line(partial_.data(), partial_.size());
    partial_.clear();
  }

  const std::string& declarations() const { return header_; }
  size_t size() const { return codes_.size(); }

  // "identifier toggles" lines, one per identifier seen in the value changes.
  bool write(const char* path) const {
    FILE* o = std::fopen(path, "w");
    if (!o) return false;
    for (size_t k = 0; k < codes_.size(); k++)
      std::fprintf(o, "%s %llu\n", codes_[k].c_str(),
                   static_cast<unsigned long long>(toggles_[k]));
    return std::fclose(o) == 0;
  }

  // Forget the counts (the identifiers and declarations stay).
  void reset_counts() {
    for (auto& t : toggles_) t = 0;
  }

 private:
  void line(const char* s, size_t len) {
    while (len > 0 && (s[len - 1] == '\r' || s[len - 1] == ' ')) len--;
    if (len == 0) return;
    if (!body_) {
      header_.append(s, len);
      header_.push_back('\n');
      body_ = std::string_view(s, len).find("$enddefinitions") != std::string_view::npos;
      return;
    }
    const char c = s[0];
    if (c == 'b' || c == 'B') {
      const char* sp = static_cast<const char*>(std::memchr(s, ' ', len));
      if (sp) change(sp + 1, len - (sp + 1 - s), s + 1, sp - s - 1);
    } else if (c == '0' || c == '1' || c == 'x' || c == 'X' || c == 'z' || c == 'Z') {
      change(s + 1, len - 1, s, 1);
    }  // '#' times, $dumpvars/$end and reals ('r') are not bit changes
  }

  void change(const char* code, size_t code_len, const char* value, size_t value_len) {
    key_.assign(code, code_len);
    auto it = index_.find(key_);
    if (it == index_.end()) {
      index_.emplace(key_, codes_.size());
      codes_.push_back(key_);
      last_.emplace_back(value, value_len);
      toggles_.push_back(0);
      return;
    }
    std::string& old = last_[it->second];
    const size_t n = std::max(old.size(), value_len);
    uint64_t t = 0;
    for (size_t i = 0; i < n; i++) {  // right-aligned; missing leading digits are 0
      const char a = i < old.size() ? old[old.size() - 1 - i] : '0';
      const char b = i < value_len ? value[value_len - 1 - i] : '0';
      t += (a == '1') != (b == '1');
    }
    toggles_[it->second] += t;
    old.assign(value, value_len);
  }

  bool body_ = false;
  std::string header_, partial_, key_;
  std::unordered_map<std::string, size_t> index_;
  std::vector<std::string> codes_, last_;
  std::vector<uint64_t> toggles_;
};

// Count the VCD file at `vcd` and write its counts to `out`. Returns the number of identifiers,
// or -1 if a file cannot be opened.
inline int64_t count_file(const char* vcd, const char* out) {
  FILE* f = std::fopen(vcd, "rb");
  if (!f) return -1;
  Counter c;
  std::vector<char> buf(1 << 20);
  size_t got;
  while ((got = std::fread(buf.data(), 1, buf.size(), f)) > 0) c.feed(buf.data(), got);
  std::fclose(f);
  c.finish();
  return c.write(out) ? static_cast<int64_t>(c.size()) : -1;
}

}  // namespace rf_toggles

#ifdef VERILATOR_VERILATED_VCD_C_H_
namespace rf_toggles {
// A "file" for VerilatedVcdC that counts the text it is given instead of writing it.
class CountingFile : public VerilatedVcdFile {
 public:
  explicit CountingFile(Counter* c) : c_(c) {}
  bool open(const std::string&) override { return true; }
  void close() override { c_->finish(); }
  ssize_t write(const char* bufp, ssize_t len) override {
    c_->feed(bufp, static_cast<size_t>(len));
    return len;
  }

 private:
  Counter* c_;
};
}  // namespace rf_toggles
#endif
