// DEVELOPMENT ONLY: the replay before warps and the memory hierarchy, for differential tests.
// RT-unit scheduler of driver/rtunit.py: P fresh model instances clocked together, a pool of R
// ray slots, each ray's recorded request chain issued one request at a time. The requests are
// assembled by the same NodeSource as the streaming fast path (rf_sim.h).
#include <cstdint>
#include <cstring>
#include <deque>
#include <memory>
#include <queue>
#include <vector>

#include "rf_memory_legacy.h"
#include "rf_sim.h"

using namespace rf;

#pragma GCC visibility push(default)
extern "C" {

// RT-unit replay (driver/rtunit.py). The m recorded requests (ray[i], ptr[i], ext[i]) form one
// chain per ray; chain_idx lists the record indices of ray r's chain, in issue order, at
// chain_idx[chain_off[r] .. chain_off[r + 1]). Chains (world rays) enter a pool of `slots` ray
// slots in the order `order` (n_chains chain indices, a permutation; null: index order; chains
// that are empty are skipped) and leave it when their chain is done.
// chain[i] is the chain (world ray) of request i: a ray that enters an instance continues its
// chain with requests on another ray-table row (its object-space ray), so ray[i] names the row
// (and the tag), chain[i] the ray slot. before[i] (kNoChild: none) is a node fetched before
// request i's own node: the instance node a ray reads on entering the instance.
//
// Every cycle, first each pipeline's response (if out_valid) is taken: its ray becomes ready
// `turnaround` cycles later (or leaves the pool, and the next ray enters, ready `turnaround`
// cycles later). Then each pipeline, in order 0..P-1, whose input is ready accepts the next
// request of the ray that has been ready longest (rays ordered by ready time, then by the order in
// which they became waiting; a new ray ready at cycle 0 initially). Then all pipelines are
// clocked. A ray has at most one request in flight.
//
// Node memory (rf_memory.h; off when cache_bytes < 0, no cache when 0): when a ray's next request becomes known
// (the cycle it would be ready), its node is fetched through the node cache; the ray is ready when
// its node's lines are present (at once on a hit, later on a miss), while other rays keep the
// pipelines busy. Returns -4 for a cache geometry it cannot model.
//
// Node-affinity scheduling (window > 0; window >= slots): the RT unit holds `window` rays (a ray
// buffer filled in `order`), of which at most `slots` hold an issue slot. A ray whose next node is
// not present in the node cache (a look at the tags, NodeMemory::present) does not wait in its
// slot: its fetch is started and the ray is parked; its slot goes to a waiting ray whose node is
// in the cache: first the parked rays whose node has arrived (earliest arrival first), then a
// new ray from the buffer while fewer than `window` rays are held. A resumed ray takes the node
// its fetch delivered (as a ray waiting in its slot does) without a second cache access; its
// lines become the most recently used. sched (int64[4]): rays parked, resumed, most rays
// parked at once, most rays held.
// window == 0: no parking, every ray waits in its slot (the behaviour above, cycle for cycle).
//
// Treelet scheduling (window > 0 and treelet != null; Aila & Karras, HPG 2010): the BVH is cut
// into n_treelets treelets; treelet[i] is the treelet of request i's node. Every held ray that
// holds no issue slot waits in the queue (FIFO) of the treelet of its next node; new rays (up to
// `window` held) join the queue of their first node's treelet. At most `active_treelets`
// treelets are active at once. Free slots go to the parked rays whose node has arrived, then to
// the rays queued on active treelets (the earliest activated treelet first); when no active
// treelet has a queued ray and fewer than `active_treelets` are active, the unit picks the
// treelet with the most queued rays (ties: the lowest index) and activates it. A ray's node is
// fetched when it takes a slot. A ray in a slot keeps it while its next node is in an active
// treelet; a ray whose next node is in an inactive treelet gives up its slot and joins that
// treelet's queue; a treelet with no ray queued, parked or in a slot is retired.
// treelet_flags bit 0 (park): a ray whose node misses parks as with node affinity (above) and
// stays a member of its treelet; else it waits in its slot. Bit 1 (borrow): when no further
// treelet may be activated, a free slot takes the first ray of the longest queue without
// activating its treelet (for one request, unless its next node is in an active treelet).
// Prefetch (tl_off != null): when a treelet is activated, every node of it (tl_node_off /
// tl_node_bytes; treelet t's nodes at [tl_off[t], tl_off[t + 1])) is fetched through the node
// cache at once. sched[4]: picks (treelet activations); sched[5]: most rays queued at once;
// sched[6]: rays given a slot by borrowing.
//
// skip_idle: a pipeline that holds no request at the start of a cycle and gets none is not
// evaluated in that cycle (clock gating: with nothing valid inside, a clock edge changes no state
// of the RayFlex pipeline, whose registers load only on a handshake); cycles still count.
//
// rsp: (m, kRspWords), written at the record index. stats: the ReplayStats of rf_layout.h (its
// fields are documented in driver/layout.py). per_pipe (int64[P]): requests per pipeline.
// Returns 0, -1 on a deadlock, -2 on a bad node pointer, -3 on bad arguments.
int64_t rf_replay_legacy(int64_t pipelines, int64_t slots, int64_t turnaround, int64_t skip_idle,
                  const uint32_t* rays, int64_t n_rays, const uint32_t* image,
                  int64_t image_words, const uint32_t* ray, const uint32_t* ptr,
                  const uint32_t* ext, int64_t m, const int64_t* chain_idx,
                  const int64_t* chain_off, int64_t n_chains, const uint32_t* chain,
                  const uint32_t* before, uint32_t* rsp, ReplayStats* stats, int64_t* per_pipe,
                  int64_t max_idle, int64_t cache_bytes, int64_t ways, int64_t line_bytes,
                  int64_t mem_latency, double bytes_per_cycle, const int64_t* order,
                  int64_t window, int64_t* sched, const int32_t* treelet, int64_t n_treelets,
                  int64_t active_treelets, const int64_t* tl_off, const int64_t* tl_node_off,
                  const int64_t* tl_node_bytes, int64_t treelet_flags) {
  if (pipelines < 1 || slots < 1 || turnaround < 0 || n_rays < 0 || n_chains < 0 || m < 0)
    return -3;
  if (window < 0 || (window > 0 && window < slots)) return -3;
  if (treelet && (window == 0 || n_treelets < 1 || active_treelets < 1)) return -3;
  for (int64_t i = 0; treelet && i < m; i++)
    if (treelet[i] < 0 || treelet[i] >= n_treelets) return -3;
  const bool treelets = treelet != nullptr;
  const bool affinity = window > 0 && !treelets;
  const bool parking = affinity || (treelets && (treelet_flags & 1));
  LegacyNodeMemory mem;
  if (!mem.configure(cache_bytes, ways, line_bytes, mem_latency, bytes_per_cycle)) return -4;
  const NodeSource src{rays, image, image_words, ray, ptr, ext};
  std::vector<std::unique_ptr<Sim>> sims;
  for (int64_t p = 0; p < pipelines; p++) {
    sims.emplace_back(new_sim());
    src.begin(sims.back()->top.req_i.data());
  }
  std::vector<std::deque<int64_t>> inflight(pipelines);   // record indices, in request order
  std::vector<int64_t> pos(n_chains, 0);                   // next chain position of each ray
  // Rays waiting to issue, earliest ready first, ties in the order they started waiting (without
  // a node memory, ready times grow with that order and this is a FIFO).
  struct Ready {
    int64_t ray, at, seq;
    bool operator>(const Ready& o) const { return at != o.at ? at > o.at : seq > o.seq; }
  };
  std::priority_queue<Ready, std::vector<Ready>, std::greater<Ready>> ready;
  std::priority_queue<Ready, std::vector<Ready>, std::greater<Ready>> parked;  // by arrival
  int64_t seq = 0, node_wait = 0;
  int64_t active = 0, held = 0;             // rays holding a slot; rays held (affinity)
  int64_t n_parked = 0, n_resumed = 0, max_parked = 0, max_held = 0;
  auto node_of = [&](int64_t r, int64_t* off) {          // ray r's next node: bytes, *off
    const uint32_t p = ptr[chain_idx[chain_off[r] + pos[r]]];
    *off = NodeSource::node_word(p) * 4;
    return static_cast<int64_t>(kNodeBytes[p & kTypeMask]);  // 0: the node the ray already holds
  };
  auto wait = [&](int64_t r, int64_t at) {                // ray r's next request, known at `at`
    const uint32_t b = before[chain_idx[chain_off[r] + pos[r]]];
    const int64_t after =
        b == kNoChild ? at : mem.fetch(NodeSource::node_word(b) * 4, kNodeBytes[b & kTypeMask], at);
    int64_t off;
    const int64_t bytes = node_of(r, &off);
    const bool park = parking && bytes && !mem.present(off, bytes, after);
    const int64_t when = bytes ? mem.fetch(off, bytes, after) : after;
    node_wait += when - at;
    if (!park) {
      ready.push({r, when, seq++});
      return;
    }
    parked.push({r, when, seq++});
    active--;
    n_parked++;
    if (static_cast<int64_t>(parked.size()) > max_parked) max_parked = parked.size();
  };
  int64_t next_ray = 0;
  auto next_in_order = [&]() -> int64_t {                  // next ray with a non-empty chain
    while (next_ray < n_chains) {
      const int64_t r = order ? order[next_ray] : next_ray;
      next_ray++;
      if (chain_off[r + 1] != chain_off[r]) return r;
    }
    return -1;
  };
  // Treelet scheduling state: per treelet its queue (ray, cycle its next request is known), its
  // members (rays in slots or parked), whether it is active; the active treelets in activation
  // order; the treelet of each ray holding a slot or parked.
  std::vector<std::deque<std::pair<int64_t, int64_t>>> tq(treelets ? n_treelets : 0);
  std::vector<int64_t> tl_members(tq.size(), 0), cur_tl(treelets ? n_chains : 0, -1);
  std::vector<char> tl_active(tq.size(), 0);
  std::vector<int64_t> act;
  int64_t queued = 0, max_queued = 0, picks = 0, n_borrowed = 0;
  auto tl_of = [&](int64_t r) {                          // the treelet of ray r's next node
    return static_cast<int64_t>(treelet[chain_idx[chain_off[r] + pos[r]]]);
  };
  auto enqueue = [&](int64_t r, int64_t at) {
    tq[tl_of(r)].push_back({r, at});
    if (++queued > max_queued) max_queued = queued;
  };
  auto enter = [&](int64_t at) {
    const int64_t r = next_in_order();
    if (r < 0) return;
    if (++held > max_held) max_held = held;
    if (treelets) {
      enqueue(r, at);
      return;
    }
    active++;
    wait(r, at);
  };
  // Affinity: give free slots to parked rays whose node has arrived, then to new rays.
  auto resume = [&](int64_t k) {                         // a parked ray whose node arrived
    if (parked.empty() || parked.top().at > k) return false;
    const int64_t r = parked.top().ray;
    parked.pop();
    n_resumed++;
    active++;
    int64_t off;
    const int64_t bytes = node_of(r, &off);
    if (bytes) mem.touch(off, bytes);
    ready.push({r, k, seq++});
    return true;
  };
  auto fill = [&](int64_t k, int64_t new_at) {
    while (active < slots) {
      if (resume(k)) continue;
      if (held >= window || next_ray >= n_chains) break;
      enter(new_at);
    }
  };
  // Treelets: new rays join their queues; retired treelets leave the active set; free slots go
  // to rays queued on active treelets, activating the treelet with the most queued rays when no
  // active treelet has one.
  auto fill_treelets = [&](int64_t k, int64_t new_at) {
    while (held < window && next_ray < n_chains) enter(new_at);
    size_t j = 0;
    for (size_t a = 0; a < act.size(); a++) {
      const int64_t t = act[a];
      if (tq[t].empty() && tl_members[t] == 0) tl_active[t] = 0;
      else act[j++] = t;
    }
    act.resize(j);
    while (active < slots) {
      if (resume(k)) continue;
      int64_t from = -1;
      for (const int64_t t : act)
        if (!tq[t].empty()) { from = t; break; }
      if (from < 0) {
        if (queued == 0) break;
        int64_t best = -1;
        for (int64_t t = 0; t < n_treelets; t++)
          if (!tl_active[t] && (best < 0 || tq[t].size() > tq[best].size())) best = t;
        if (best < 0 || tq[best].empty()) break;
        if (static_cast<int64_t>(act.size()) >= active_treelets) {
          if (!(treelet_flags & 2)) break;
          n_borrowed++;                         // a free slot serves the longest queue
        } else {
          tl_active[best] = 1;
          act.push_back(best);
          picks++;
          if (tl_off)
            for (int64_t e = tl_off[best]; e < tl_off[best + 1]; e++)
              mem.fetch(tl_node_off[e], tl_node_bytes[e], k);
        }
        from = best;
      }
      const auto [r, at] = tq[from].front();
      tq[from].pop_front();
      queued--;
      active++;
      tl_members[from]++;
      cur_tl[r] = from;
      wait(r, at > k ? at : k);
    }
  };
  if (treelets) {
    fill_treelets(0, 0);
  } else if (affinity) {
    fill(0, 0);
  } else {
    for (int64_t s = 0; s < slots && next_ray < n_chains; s++) enter(0);
  }

  int64_t taken = 0, k = 0, first = -1, last = -1, idle = 0, evals = 0, starved = 0;
  int64_t full_cycles = 0, bad_tags = 0, accepts = 0;
  std::vector<char> busy(pipelines);
  for (int64_t p = 0; p < pipelines; p++) per_pipe[p] = 0;
  while (taken < m) {
    bool progress = false;
    for (int64_t p = 0; p < pipelines; p++) {
      Vrayflex& t = sims[p]->top;
      busy[p] = !inflight[p].empty();
      t.out_ready_i = 1;
      if (!(busy[p] && t.out_valid_o)) continue;
      const int64_t i = inflight[p].front();
      inflight[p].pop_front();
      std::memcpy(rsp + i * kRspWords, t.rsp_o.data(), kRspWords * 4);
      if (rsp[i * kRspWords] != ray[i]) bad_tags++;
      taken++;
      last = k;
      progress = true;
      const int64_t r = chain[i];
      const bool more = ++pos[r] < chain_off[r + 1] - chain_off[r];
      if (treelets) {
        tl_members[cur_tl[r]]--;
        if (more && tl_active[tl_of(r)]) {          // stays in its slot
          cur_tl[r] = tl_of(r);
          tl_members[cur_tl[r]]++;
          wait(r, k + turnaround);
        } else {
          active--;
          if (more) enqueue(r, k + turnaround);
          else held--;
        }
      } else if (more) {
        wait(r, k + turnaround);
      } else {
        active--;
        held--;
        if (!affinity) enter(k + turnaround);
      }
    }
    if (treelets) fill_treelets(k, k + turnaround);
    else if (affinity) fill(k, k + turnaround);
    int64_t issued = 0;
    for (int64_t p = 0; p < pipelines; p++) {
      Vrayflex& t = sims[p]->top;
      t.in_valid_i = 0;
      if (ready.empty() || ready.top().at > k || !t.in_ready_o) continue;
      const int64_t r = ready.top().ray;
      ready.pop();
      const int64_t i = chain_idx[chain_off[r] + pos[r]];
      if (!src.fill(i, t.req_i.data())) return -2;
      if (!ready.empty()) {                       // the next ray to issue, if it is known
        const Ready& nx = ready.top();
        if (pos[nx.ray] < chain_off[nx.ray + 1] - chain_off[nx.ray])
          src.prefetch(chain_idx[chain_off[nx.ray] + pos[nx.ray]]);
      }
      t.in_valid_i = 1;
      inflight[p].push_back(i);
      per_pipe[p]++;
      issued++;
      if (first < 0) first = k;
      progress = true;
    }
    accepts += issued;
    if (issued == pipelines) full_cycles++;
    if (issued < pipelines && (ready.empty() || ready.top().at > k)) starved++;
    for (int64_t p = 0; p < pipelines; p++) {
      if (skip_idle && !busy[p] && !sims[p]->top.in_valid_i) continue;
      tick(sims[p].get());
      evals++;
    }
    if (!ready.empty() && ready.top().at > k) progress = true;   // waiting on a node fetch
    if (!parked.empty() && parked.top().at > k) progress = true;
    if (queued && active) progress = true;             // queued rays wait for their treelet
    idle = progress ? 0 : idle + 1;
    if (idle > max_idle + turnaround) return -1;
    k++;
  }
  stats->cycles = m ? last - first + 1 : 0;
  stats->model_evals = evals;
  stats->starved_cycles = starved;
  stats->full_cycles = full_cycles;
  stats->first_accept = first;
  stats->last_response = last;
  stats->bad_tags = bad_tags;
  stats->accepts = accepts;
  stats->line_accesses = mem.line_accesses;
  stats->line_hits = mem.line_hits;
  stats->line_misses = mem.line_misses;
  stats->bytes_from_memory = mem.bytes_from_memory;
  stats->node_wait_cycles = node_wait;
  if (sched) {
    sched[0] = n_parked;
    sched[1] = n_resumed;
    sched[2] = max_parked;
    sched[3] = max_held;
    sched[4] = picks;
    sched[5] = max_queued;
    sched[6] = n_borrowed;
  }
  return 0;
}

}  // extern "C"
#pragma GCC visibility pop

