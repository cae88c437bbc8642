"""RT-unit presets: a whole RT-unit configuration at once (``--rt-preset``, docs/rtunit.md).

Each preset is a set of design-point values (``driver.design`` option names) with, for every
value, where it comes from. docs/rtunit.md's preset table is this table (a test compares them).

- ``default``: the RT unit this tool has always modelled (one unit, a pool of 64 rays, one
  pipeline, a 32 KiB 4-way node cache of 64-byte lines, a memory 200 cycles and 32 bytes per
  cycle away), issued as a GPU does: one kernel, threads' rays in program order.
- ``rtx2060-vulkan-sim``: Vulkan-Sim's RTX 2060 configuration (Saed et al., "Vulkan-Sim: A GPU
  Architecture Simulator for Ray Tracing", MICRO 2022; its ``configs/tested-cfgs/SM75_RTX2060/
  gpgpusim.config``), with our RTL as the datapath where Vulkan-Sim has fixed latencies.
"""

from __future__ import annotations

from dataclasses import dataclass

CONFIG = "Vulkan-Sim configs/tested-cfgs/SM75_RTX2060/gpgpusim.config"
DEFAULT_PRESET = "default"

# RTX 2060 DRAM bandwidth in bytes per core cycle: 12 channels x 2-byte bus x 3500 MHz x 4
# (-gpgpu_n_mem 12, -gpgpu_dram_buswidth 2, DRAM clock 3500 MHz, -dram_data_command_freq_ratio
# 4: 336 GB/s, NVIDIA's figure for the RTX 2060) over the 1365 MHz core clock
RTX2060_BYTES_PER_CYCLE = round(12 * 2 * 3500e6 * 4 / 1365e6, 1)


@dataclass(frozen=True)
class Preset:
    name: str
    help: str
    values: dict          # design-point option name -> value
    sources: dict         # option name -> where the value comes from


PRESETS = {p.name: p for p in (
    Preset("default", "one RT unit as modelled before warps (64 rays, 32 KiB node cache, memory "
           "200 cycles and 32 B/cycle away), in a one-kernel frame", {
               "frame_schedule": "one-kernel", "shader_cycles": 0, "flush_between": False,
               "warp_size": 1, "warps_per_unit": 0, "rt_units": 1, "rays_in_flight": 64,
               "pipelines": 1, "cache_kib": 32, "cache_ways": 4, "cache_latency": 0,
               "mshrs": 0, "l2_kib": 0, "l2_ways": 16, "l2_latency": 0, "line_bytes": 64,
               "sector_bytes": 0, "mem_latency": 200, "mem_bytes_per_cycle": 32.0},
           {"frame_schedule": "a DXR/Vulkan dispatch is one kernel",
            "warp_size": "1: every ray issued on its own, as the per-ray pool",
            "warps_per_unit": "0: twice the warps the ray pool holds"}),
    Preset("rtx2060-vulkan-sim", "Vulkan-Sim's RTX 2060: 30 RT units, warps of 32, 4 warps "
           "per unit, 64 KiB L1, 3 MiB L2, 64 MSHRs, 32-byte sectors", {
               "frame_schedule": "one-kernel", "shader_cycles": 0, "flush_between": False,
               "warp_size": 32, "warps_per_unit": 32, "rt_units": 30, "rays_in_flight": 128,
               "pipelines": 1, "cache_kib": 64, "cache_ways": 512, "cache_latency": 20,
               "mshrs": 64, "l2_kib": 3072, "l2_ways": 16, "l2_latency": 160,
               "line_bytes": 128, "sector_bytes": 32, "mem_latency": 100,
               "mem_bytes_per_cycle": RTX2060_BYTES_PER_CYCLE},
           {"frame_schedule": "Vulkan-Sim runs a ray-tracing pipeline as one kernel (MICRO 2022, "
                     "section 3)",
            "warp_size": "NVIDIA warps of 32 threads (MICRO 2022, section 2)",
            "warps_per_unit": f"-gpgpu_shader_core_pipeline 1024:32 ({CONFIG}): at most 32 "
                              "warps resident per SM",
            "rt_units": "-gpgpu_n_clusters 30, -gpgpu_n_cores_per_cluster 1, "
                        "-gpgpu_num_rt_core_units 1: 30 SMs with one RT unit each",
            "rays_in_flight": "-gpgpu_rt_max_warps 4: 4 warps of 32 rays in an RT unit",
            "pipelines": "our RTL: one box or triangle test per cycle per pipeline (Vulkan-Sim: "
                         "fixed intersection latencies, -gpgpu_rt_intersection_latency)",
            "cache_kib": "-gpgpu_rt_use_l1 1 with -gpgpu_cache:dl1 S:1:128:512: the RT unit "
                         "fetches through the SM's 64 KiB L1D (1 set x 512 ways x 128 B)",
            "cache_ways": "-gpgpu_cache:dl1 S:1:128:512: 512 ways, one set (fully associative)",
            "cache_latency": "-gpgpu_l1_latency 20",
            "mshrs": "-gpgpu_rt_max_mshr 64",
            "l2_kib": "-gpgpu_cache:dl2 S:64:128:16 per memory sub-partition (128 KiB), x 24 "
                      "sub-partitions (-gpgpu_n_mem 12, -gpgpu_n_sub_partition_per_mchannel 2): "
                      "3 MiB",
            "l2_ways": "-gpgpu_cache:dl2 S:64:128:16: 16 ways",
            "l2_latency": "-gpgpu_l2_rop_latency 160",
            "line_bytes": "128-byte lines in dl1 and dl2 (S:1:128:512, S:64:128:16)",
            "sector_bytes": "sectored caches (S:) of 32-byte sectors: node fetches are split "
                            "into 32-byte transactions",
            "mem_latency": "-dram_latency 100",
            "mem_bytes_per_cycle": "12 channels x 2 B x 3500 MHz x 4 (-gpgpu_n_mem 12, "
                                   "-gpgpu_dram_buswidth 2, -gpgpu_clock_domains "
                                   "1365:1365:1365:3500, -dram_data_command_freq_ratio 4) = "
                                   "336 GB/s, over the 1365 MHz core clock"}),
)}


def table() -> list[tuple[str, dict]]:
    """(option name, {preset: value}) for every option a preset sets, in the presets' order."""
    names = list(dict.fromkeys(k for p in PRESETS.values() for k in p.values))
    return [(n, {p.name: p.values.get(n) for p in PRESETS.values()}) for n in names]


def markdown() -> str:
    """docs/rtunit.md's preset table: every value of every preset and where the Vulkan-Sim
    preset's comes from."""
    names = list(PRESETS)
    last = PRESETS[names[-1]]
    lines = ["| option | " + " | ".join(f"`{n}`" for n in names)
             + f" | where the `{last.name}` value comes from |",
             "|---|" + "---|" * len(names) + "---|"]
    for opt, values in table():
        lines.append(f"| `{opt}` | " + " | ".join(str(values[n]) for n in names)
                     + f" | {last.sources.get(opt, '')} |")
    return "\n".join(lines)
