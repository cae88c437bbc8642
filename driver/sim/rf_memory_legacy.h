// Node memory of the RT-unit model: a set-associative LRU node cache in front of a memory with a
// fixed latency and a bandwidth limit (driver/rtunit.py, MemoryModel).
//
// A request needs its node's bytes (kNodeBytes by pointer type: a box32 box node 128 bytes, a q8
// box node, a triangle node and a pair leaf 64; a pair's second triangle none more: the ray holds
// that node) before it can issue. `fetch` looks up every cache line the node touches at
// cycle `now` and returns the cycle at which the last of them is present:
//  - a line in the cache whose fill has arrived: a hit, present now;
//  - a line in the cache whose fill is still under way (another ray missed on it): a hit on the
//    pending fill (no new traffic), present when that fill arrives;
//  - a miss: the line is requested from memory on the one channel: its transfer starts when the
//    channel is free (transfers are serialised: line_bytes / bytes_per_cycle cycles each) and
//    the line arrives `latency` cycles after its transfer ends; it is installed at once (as the
//    LRU's most recent entry), replacing the least recently used line of its set.
// No cache (cache_bytes == 0): every line a node touches is fetched from memory on every access
// (nothing is kept, nothing is shared between rays). Disabled (cache_bytes < 0): every node is
// present at once, and the replay is the one without a memory model, cycle for cycle.
#pragma once

#include <cstdint>
#include <vector>

namespace rf {

struct LegacyNodeMemory {
  int64_t line_bytes = 64, ways = 4, sets = 0, latency = 0;
  double cycles_per_line = 0;      // transfer time of one line on the memory channel
  double channel_free = 0;         // cycle at which the channel can start the next transfer
  std::vector<int64_t> tag;        // [set * ways + way]: line address, -1 = empty
  std::vector<int64_t> used;       // LRU stamp of each entry
  std::vector<int64_t> arrive;     // cycle at which the entry's fill arrives
  int64_t stamp = 0;
  int64_t line_accesses = 0, line_hits = 0, line_misses = 0, bytes_from_memory = 0;
  bool on = false;                 // a memory model at all (cache_bytes >= 0)

  bool enabled() const { return on; }

  // Returns false for a geometry that is not a whole number of sets of power-of-two lines.
  bool configure(int64_t cache_bytes, int64_t ways_, int64_t line_bytes_, int64_t latency_,
                 double bytes_per_cycle) {
    if (cache_bytes < 0) return true;
    if (ways_ < 1 || line_bytes_ < 4 || (line_bytes_ & (line_bytes_ - 1)) || latency_ < 0 ||
        !(bytes_per_cycle > 0) || cache_bytes % (ways_ * line_bytes_))
      return false;
    on = true;
    line_bytes = line_bytes_;
    ways = ways_;
    sets = cache_bytes / (ways * line_bytes);
    latency = latency_;
    cycles_per_line = static_cast<double>(line_bytes) / bytes_per_cycle;
    tag.assign(sets * ways, -1);
    used.assign(sets * ways, 0);
    arrive.assign(sets * ways, 0);
    return true;
  }

  // The cycle at which line `line` (a line address: byte offset / line_bytes) is present.
  int64_t line(int64_t addr, int64_t now) {
    line_accesses++;
    if (sets == 0) {               // no cache: the line comes from memory, and is not kept
      line_misses++;
      bytes_from_memory += line_bytes;
      const double start = channel_free > now ? channel_free : static_cast<double>(now);
      channel_free = start + cycles_per_line;
      return static_cast<int64_t>(channel_free + 0.999999999) + latency;
    }
    const int64_t set = addr % sets;
    int64_t* t = &tag[set * ways];
    int64_t victim = 0;
    for (int64_t w = 0; w < ways; w++) {
      if (t[w] == addr) {
        line_hits++;
        used[set * ways + w] = ++stamp;
        return arrive[set * ways + w] > now ? arrive[set * ways + w] : now;
      }
      if (used[set * ways + w] < used[set * ways + victim]) victim = w;
    }
    line_misses++;
    bytes_from_memory += line_bytes;
    const double start = channel_free > now ? channel_free : static_cast<double>(now);
    channel_free = start + cycles_per_line;
    const int64_t at = static_cast<int64_t>(channel_free + 0.999999999) + latency;
    const int64_t e = set * ways + victim;
    t[victim] = addr;
    used[e] = ++stamp;
    arrive[e] = at;
    return at;
  }

  // Whether line `addr` is in the cache with its fill arrived by cycle `now` (no side effects).
  bool has(int64_t addr, int64_t now) const {
    if (sets == 0) return false;
    const int64_t set = addr % sets;
    for (int64_t w = 0; w < ways; w++)
      if (tag[set * ways + w] == addr) return arrive[set * ways + w] <= now;
    return false;
  }

  // Whether all of a node's bytes are present at cycle `now` (no side effects: a scheduler's look
  // at the cache tags).
  bool present(int64_t byte_offset, int64_t bytes, int64_t now) const {
    if (!enabled()) return true;
    for (int64_t a = byte_offset / line_bytes; a <= (byte_offset + bytes - 1) / line_bytes; a++)
      if (!has(a, now)) return false;
    return true;
  }

  // Marks a present node's lines most recently used without counting an access (a ray that
  // waited for the node takes it once its fill has arrived: the access was counted when the
  // ray asked for the node).
  void touch(int64_t byte_offset, int64_t bytes) {
    if (!enabled() || sets == 0) return;
    for (int64_t a = byte_offset / line_bytes; a <= (byte_offset + bytes - 1) / line_bytes; a++) {
      const int64_t set = a % sets;
      for (int64_t w = 0; w < ways; w++)
        if (tag[set * ways + w] == a) used[set * ways + w] = ++stamp;
    }
  }

  // The cycle at which all of a node's bytes [byte_offset, byte_offset + bytes) are present.
  int64_t fetch(int64_t byte_offset, int64_t bytes, int64_t now) {
    if (!enabled()) return now;
    int64_t ready = now;
    for (int64_t a = byte_offset / line_bytes; a <= (byte_offset + bytes - 1) / line_bytes; a++) {
      const int64_t at = line(a, now);
      if (at > ready) ready = at;
    }
    return ready;
  }
};

}  // namespace rf
