// The memory hierarchy of the RT-unit model (driver.rtunit.MemoryModel, docs/rtunit.md): per RT
// unit a node cache (L1) with a hit latency and a file of MSHRs, an L2 shared by all units, and a
// DRAM channel shared by all units.
//
// A request needs its node's bytes (kNodeBytes by pointer type: a box32 box node 128 bytes, a q8
// box node, a triangle node and a pair leaf 64; a pair's second triangle none more: the ray holds
// that node) before it can issue. The bytes move in transactions: whole lines, or `sector_bytes`
// sectors of a line (a sectored cache keeps one tag per line and a valid bit per sector; a miss
// fetches only the sectors it needs). `fetch` looks up every transaction the node touches at cycle
// `now` and returns the cycle at which the last of them is present, and the level it waited on:
//  - L1 hit (the transaction present): present `l1_latency` cycles later;
//  - L1 hit on a pending fill (another ray missed on it and its data is still under way): merged,
//    no new traffic, present when that fill arrives (and not before the hit latency);
//  - L1 miss: the unit needs a free MSHR (`mshrs` 0: unlimited; a full MSHR file holds the miss
//    until the earliest outstanding miss returns); the request reaches the L2 `l1_latency` cycles
//    later. The L2 (shared; `l2_bytes` 0: none) hits `l2_latency` cycles later, merges on its own
//    pending fills, or misses: the transaction goes to DRAM `l2_latency` cycles later. DRAM
//    transfers are serialised on one channel at `bytes_per_cycle` and a transaction arrives
//    `mem_latency` cycles after its transfer. A miss installs the line at once (the most recent of
//    its set; replacing the least recently used line of the set), with its fill's arrival time.
// No L1 (`l1_bytes` 0): every transaction goes to the next level on every access (nothing is kept,
// nothing merged). Disabled (`l1_bytes` < 0): every node is present at once, and the replay is the
// one without a memory model, cycle for cycle.
//
// Why the times are computed when a node is asked for (not simulated cycle by cycle): every
// latency is fixed and the channel and the MSHRs serve requests in the order they are asked for,
// so a request's arrival is known the moment it is made; the replay's rays then wait for it.
// The caches are set-associative LRU with a recency list per set; a look-up scans a set of up to
// 16 ways and uses a hash table from line to entry beyond, so a fully associative 64 KiB L1 (512
// ways) costs what a 4-way one does.
#pragma once

#include <algorithm>
#include <cstdint>
#include <functional>
#include <queue>
#include <vector>

#include "rf_layout.h"

namespace rf {

constexpr int64_t kAbsent = INT64_MIN;   // a sector that is not in the cache
using rf_layout::Level;            // generated from driver.core.layout.MEMORY_LEVELS, as are
using rf_layout::kLevelNone;       // the level count kMemoryLevels and the names below
using rf_layout::kLevelL1;
using rf_layout::kLevelL2;
using rf_layout::kLevelDram;
using rf_layout::kMemoryLevels;

// Open-addressing hash table: line address (>= 0) -> entry index; linear probing, deletion by
// backward shift (no tombstones).
class LineTable {
 public:
  void reset(int64_t entries) {
    int64_t cap = 16;
    while (cap < 2 * entries) cap <<= 1;
    key_.assign(cap, -1);
    val_.assign(cap, -1);
    mask_ = cap - 1;
  }
  void clear() {
    std::fill(key_.begin(), key_.end(), -1);
  }
  int32_t find(int64_t line) const {
    for (int64_t i = hash(line);; i = (i + 1) & mask_) {
      if (key_[i] == line) return val_[i];
      if (key_[i] < 0) return -1;
    }
  }
  void put(int64_t line, int32_t entry) {
    int64_t i = hash(line);
    while (key_[i] >= 0 && key_[i] != line) i = (i + 1) & mask_;
    key_[i] = line;
    val_[i] = entry;
  }
  void erase(int64_t line) {
    int64_t i = hash(line);
    while (key_[i] != line) {
      if (key_[i] < 0) return;
      i = (i + 1) & mask_;
    }
    for (int64_t j = (i + 1) & mask_;; j = (j + 1) & mask_) {
      if (key_[j] < 0) break;
      const int64_t home = hash(key_[j]);
      // move key j back to the hole at i unless its home lies cyclically in (i, j]
      const bool stays = i <= j ? (home > i && home <= j) : (home > i || home <= j);
      if (stays) continue;
      key_[i] = key_[j];
      val_[i] = val_[j];
      i = j;
    }
    key_[i] = -1;
  }

 private:
  int64_t hash(int64_t line) const {
    uint64_t x = static_cast<uint64_t>(line) * 0x9E3779B97F4A7C15ull;
    return static_cast<int64_t>((x ^ (x >> 29)) & static_cast<uint64_t>(mask_));
  }
  std::vector<int64_t> key_;
  std::vector<int32_t> val_;
  int64_t mask_ = 0;
};

// Counters of one level (docs/statistics.md, `levels`).
struct LevelCounts {
  int64_t accesses = 0, hits = 0, merged = 0, misses = 0, bytes = 0;
};

constexpr int64_t kScanWays = 16;   // up to this many ways a look-up scans the set's tags

// One set-associative LRU cache of `sectors` transactions per line.
struct Cache {
  bool on = false;
  int64_t ways = 0, sets = 0, spl = 1, latency = 0;
  std::vector<int64_t> tag;          // [entry]: line address, -1 empty
  std::vector<int32_t> prv, nxt;     // recency list of each set: head = most recent
  std::vector<int32_t> head, tail;   // [set]
  std::vector<int64_t> arrive;       // [entry * spl + sector]: cycle the fill arrives, kAbsent
  std::vector<int8_t> src;           // [entry * spl + sector]: the level the fill came from
  LineTable where;
  LevelCounts n;

  void configure(int64_t bytes, int64_t ways_, int64_t line_bytes, int64_t spl_, int64_t lat) {
    latency = lat;
    spl = spl_;
    on = bytes > 0;
    if (!on) return;
    ways = ways_;
    sets = bytes / (ways * line_bytes);
    const int64_t entries = sets * ways;
    tag.assign(entries, -1);
    prv.assign(entries, -1);
    nxt.assign(entries, -1);
    head.assign(sets, -1);
    tail.assign(sets, -1);
    arrive.assign(entries * spl, kAbsent);
    src.assign(entries * spl, 0);
    if (ways > kScanWays) where.reset(entries);
    for (int64_t s = 0; s < sets; s++) {
      for (int64_t w = 0; w < ways; w++) {
        const int32_t e = static_cast<int32_t>(s * ways + w);
        prv[e] = w ? e - 1 : -1;
        nxt[e] = w + 1 < ways ? e + 1 : -1;
      }
      head[s] = static_cast<int32_t>(s * ways);
      tail[s] = static_cast<int32_t>(s * ways + ways - 1);
    }
  }

  void flush() {
    if (!on) return;
    std::fill(tag.begin(), tag.end(), -1);
    std::fill(arrive.begin(), arrive.end(), kAbsent);
    if (ways > kScanWays) where.clear();
  }

  // The entry holding `line`, or -1: a scan of its set for a few ways, the hash table else.
  int32_t find(int64_t line) const {
    if (ways > kScanWays) return where.find(line);
    const int64_t base = (line % sets) * ways;
    for (int64_t w = 0; w < ways; w++)
      if (tag[base + w] == line) return static_cast<int32_t>(base + w);
    return -1;
  }

  void make_recent(int32_t e) {
    const int64_t s = e / ways;
    if (head[s] == e) return;
    // unlink
    nxt[prv[e]] = nxt[e];
    if (nxt[e] >= 0) prv[nxt[e]] = prv[e];
    else tail[s] = prv[e];
    // push front
    prv[e] = -1;
    nxt[e] = head[s];
    prv[head[s]] = e;
    head[s] = e;
  }

  // The least recently used entry of the line's set becomes the line's (its old line leaves).
  int32_t allocate(int64_t line) {
    const int64_t s = line % sets;
    const int32_t e = tail[s];
    if (ways > kScanWays && tag[e] >= 0) where.erase(tag[e]);
    tag[e] = line;
    std::fill(arrive.begin() + e * spl, arrive.begin() + (e + 1) * spl, kAbsent);
    if (ways > kScanWays) where.put(line, e);
    make_recent(e);
    return e;
  }
};

struct Access {
  int64_t ready;
  int level;      // the level the request waited on (docs/statistics.md: wait per level)
  int served;     // the level that supplied the bytes (a merged access: the cache it merged in)
};

using rf_layout::MemoryConfig;   // generated from driver.core.layout.MEMORY_CONFIG

struct MemorySystem {
  bool on = false;                 // a memory model at all (l1_bytes >= 0)
  int64_t line_bytes = 64, tx_bytes = 64, spl = 1, mem_latency = 0, mshrs = 0;
  double cycles_per_tx = 0;        // transfer time of one transaction on the DRAM channel
  double channel_free = 0;         // cycle at which the channel can start the next transfer
  std::vector<Cache> l1;           // one per unit
  Cache l2;
  // per unit: the cycles at which its MSHRs become free (a min-heap of `mshrs` entries)
  std::vector<std::priority_queue<int64_t, std::vector<int64_t>, std::greater<int64_t>>> mshr;
  LevelCounts dram;                // accesses = transfers
  int64_t mshr_stalls = 0, mshr_stall_cycles = 0;

  bool enabled() const { return on; }

  // Returns false for a geometry it cannot model (each cache a whole number of sets of
  // power-of-two lines, sectors a power of two dividing the line).
  bool configure(const MemoryConfig& c, int64_t units) {
    if (c.l1_bytes < 0) return true;
    const int64_t lb = c.line_bytes, sb = c.sector_bytes ? c.sector_bytes : c.line_bytes;
    if (c.l1_ways < 1 || lb < 4 || (lb & (lb - 1)) || sb < 4 || (sb & (sb - 1)) || sb > lb ||
        c.l1_latency < 0 || c.mem_latency < 0 || c.l2_latency < 0 || c.mshrs < 0 ||
        !(c.bytes_per_cycle > 0) || c.l1_bytes % (c.l1_ways * lb) || c.l2_bytes < 0 ||
        (c.l2_bytes && (c.l2_ways < 1 || c.l2_bytes % (c.l2_ways * lb))) || units < 1)
      return false;
    on = true;
    line_bytes = lb;
    tx_bytes = sb;
    spl = lb / sb;
    mem_latency = c.mem_latency;
    mshrs = c.mshrs;
    cycles_per_tx = static_cast<double>(tx_bytes) / c.bytes_per_cycle;
    l1.resize(units);
    for (auto& cache : l1) cache.configure(c.l1_bytes, c.l1_ways, lb, spl, c.l1_latency);
    l2.configure(c.l2_bytes, c.l2_ways, lb, spl, c.l2_latency);
    mshr.resize(units);
    for (auto& q : mshr)
      for (int64_t i = 0; i < mshrs; i++) q.push(0);
    return true;
  }

  void flush() {
    for (auto& cache : l1) cache.flush();
    l2.flush();
  }

  Access from_dram(int64_t t) {
    const double start = channel_free > t ? channel_free : static_cast<double>(t);
    channel_free = start + cycles_per_tx;
    dram.accesses++;
    dram.misses++;
    dram.bytes += tx_bytes;
    const int64_t at = static_cast<int64_t>(channel_free + 0.999999999) + mem_latency;
    return {at, kLevelDram, kLevelDram};
  }

  // The L2 at cycle t (the request has left its L1).
  Access from_l2(int64_t line, int64_t sector, int64_t t) {
    Cache& c = l2;
    if (!c.on) return from_dram(t);
    c.n.accesses++;
    int32_t e = c.find(line);
    if (e >= 0) {
      c.make_recent(e);
      const int64_t a = c.arrive[e * spl + sector];
      if (a != kAbsent) {
        if (a <= t) {
          c.n.hits++;
          return {t + c.latency, kLevelL2, kLevelL2};
        }
        c.n.merged++;
        const int64_t r = std::max(a, t + c.latency);
        return {r, c.src[e * spl + sector], kLevelL2};
      }
    }
    c.n.misses++;
    c.n.bytes += tx_bytes;
    const Access d = from_dram(t + c.latency);
    if (e < 0) e = c.allocate(line);
    c.arrive[e * spl + sector] = d.ready;
    c.src[e * spl + sector] = kLevelDram;
    return d;
  }

  // Transaction `tx` (byte offset / tx_bytes) of unit u, asked for at cycle `now`.
  Access transaction(int64_t u, int64_t tx, int64_t now) {
    Cache& c = l1[u];
    const int64_t line = tx / spl, sector = tx % spl;
    c.n.accesses++;
    int32_t e = -1;
    if (c.on) {
      e = c.find(line);
      if (e >= 0) {
        c.make_recent(e);
        const int64_t a = c.arrive[e * spl + sector];
        if (a != kAbsent) {
          if (a <= now) {
            c.n.hits++;
            return {now + c.latency, kLevelL1, kLevelL1};
          }
          c.n.merged++;
          return {std::max(a, now + c.latency), c.src[e * spl + sector], kLevelL1};
        }
      }
    }
    c.n.misses++;
    c.n.bytes += tx_bytes;
    int64_t start = now;
    if (mshrs) {                   // the earliest free MSHR takes the miss
      auto& q = mshr[u];
      if (q.top() > start) {
        mshr_stalls++;
        mshr_stall_cycles += q.top() - start;
        start = q.top();
      }
      q.pop();
    }
    const Access lower = from_l2(line, sector, start + c.latency);
    if (mshrs) mshr[u].push(lower.ready);
    if (c.on) {
      if (e < 0) e = c.allocate(line);
      c.arrive[e * spl + sector] = lower.ready;
      c.src[e * spl + sector] = static_cast<int8_t>(lower.level);
    }
    return lower;
  }

  // Whether all of a node's bytes are in unit u's L1 with their fills arrived by cycle `now`
  // (no side effects: a scheduler's look at the cache tags).
  bool present(int64_t u, int64_t byte_offset, int64_t bytes, int64_t now) const {
    if (!on) return true;
    const Cache& c = l1[u];
    if (!c.on) return false;
    for (int64_t t = byte_offset / tx_bytes; t <= (byte_offset + bytes - 1) / tx_bytes; t++) {
      const int32_t e = c.find(t / spl);
      if (e < 0) return false;
      const int64_t a = c.arrive[e * spl + t % spl];
      if (a == kAbsent || a > now) return false;
    }
    return true;
  }

  // Marks a present node's lines most recently used without counting an access (a ray that
  // waited for the node takes it once its fill has arrived: the access was counted when the
  // ray asked for the node).
  void touch(int64_t u, int64_t byte_offset, int64_t bytes) {
    if (!on || !l1[u].on) return;
    Cache& c = l1[u];
    for (int64_t a = byte_offset / line_bytes; a <= (byte_offset + bytes - 1) / line_bytes; a++) {
      const int32_t e = c.find(a);
      if (e >= 0) c.make_recent(e);
    }
  }

  // The cycle at which all of a node's bytes [byte_offset, byte_offset + bytes) are present in
  // unit u, and the level the last of them came from. served (int64[4], or null): bytes supplied
  // by each level (index Level), added to.
  Access fetch(int64_t u, int64_t byte_offset, int64_t bytes, int64_t now, int64_t* served) {
    if (!on) return {now, kLevelNone, kLevelNone};
    Access out{now, kLevelNone, kLevelNone};
    for (int64_t t = byte_offset / tx_bytes; t <= (byte_offset + bytes - 1) / tx_bytes; t++) {
      const Access a = transaction(u, t, now);
      if (served) served[a.served] += tx_bytes;
      if (a.ready > out.ready || (a.ready == out.ready && a.level > out.level)) out = a;
    }
    return out;
  }
};

}  // namespace rf
