"""What memory a process may still use (core.memory.memory_limits): free memory, its address-space limit less
what it has mapped, and its memory cgroup's limit less its usage (v2 and v1, at its own cgroup and each above it).
The /proc and /sys/fs/cgroup read are fake trees here, the limits set in child processes."""

import json
import subprocess
import sys

from hybrid_sysid.core.memory import (
    ADDRESS_SPACE,
    CGROUP_V1,
    CGROUP_V2,
    FREE,
    memory_limits,
    tightest_memory,
)

GIB = 2**30


def fake_proc(root, cgroup_lines, available_kib=4 * 2**20, vmsize_kib=1000):
    """A /proc with meminfo, self/status and self/cgroup."""
    (root / "self").mkdir(parents=True)
    (root / "meminfo").write_text(f"MemTotal:  99999999 kB\nMemFree:  1 kB\nMemAvailable:  {available_kib} kB\n")
    (root / "self" / "status").write_text(f"Name:\tpython\nVmPeak:\t 9999999 kB\nVmSize:\t {vmsize_kib} kB\n")
    (root / "self" / "cgroup").write_text(cgroup_lines)
    return root


def files(folder, **contents):
    folder.mkdir(parents=True, exist_ok=True)
    for name, text in contents.items():
        (folder / name.replace("_", ".", 1)).write_text(text)


def test_cgroup_v2_counts_the_tightest_level_from_the_processs_own_up(tmp_path):
    """A job's limit 2 GiB with 1 GiB used; its step below it allows 3 GiB with 2.5 GiB used: 0.5 GiB is left.
    Then the job's own usage grows to 1.75 GiB: 0.25 GiB is left, the job's level."""
    proc = fake_proc(tmp_path / "proc", "0::/job/step\n")
    cg = tmp_path / "cgroup"
    files(cg, cgroup_controllers="memory cpu\n", memory_current="123\n")  # the root: no memory.max
    files(cg / "job", memory_max=f"{2 * GIB}\n", memory_current=f"{GIB}\n")
    files(cg / "job" / "step", memory_max=f"{3 * GIB}\n", memory_current=f"{GIB * 5 // 2}\n")
    files(cg / "job" / "step" / "sibling", memory_max="1\n", memory_current="0\n")  # not the process's
    limits = memory_limits(proc, cg)
    assert limits[CGROUP_V2] == GIB // 2 and limits[FREE] == 4 * GIB and CGROUP_V1 not in limits
    (cg / "job" / "memory.current").write_text(f"{GIB * 7 // 4}\n")
    assert memory_limits(proc, cg)[CGROUP_V2] == GIB // 4
    (cg / "job" / "memory.max").write_text("max\n")
    (cg / "job" / "step" / "memory.max").write_text("max\n")
    assert CGROUP_V2 not in memory_limits(proc, cg)


def test_cgroup_v1_and_a_containers_own_view(tmp_path):
    """v1's memory controller (a hybrid layout: v2 under unified/, without a limit): 1 GiB with 256 MiB used at
    the process's cgroup, no limit (v1's huge number) at the root. Inside a container the cgroup's path is not
    under the mount, whose root is then the container's own cgroup: 1 GiB with nothing used."""
    proc = fake_proc(tmp_path / "proc", "4:memory:/docker/abc\n2:cpu,cpuacct:/docker/abc\n0::/docker/abc\n")
    cg = tmp_path / "cgroup"
    files(cg / "unified", cgroup_controllers="\n", memory_current="5\n")
    files(cg / "memory", memory_limit_in_bytes="9223372036854771712\n", memory_usage_in_bytes="1\n")
    files(cg / "memory" / "docker" / "abc", memory_limit_in_bytes=f"{GIB}\n", memory_usage_in_bytes=f"{GIB // 4}\n")
    limits = memory_limits(proc, cg)
    assert limits[CGROUP_V1] == 3 * GIB // 4 and CGROUP_V2 not in limits
    got = tightest_memory(proc, cg)
    assert got[0] <= 3 * GIB // 4 and (got[1] == CGROUP_V1 or got[1] == ADDRESS_SPACE), got  # ulimit -v of the run
    container = tmp_path / "container"
    files(container / "memory", memory_limit_in_bytes=f"{GIB}\n", memory_usage_in_bytes="0\n")
    assert memory_limits(proc, container)[CGROUP_V1] == GIB


def test_unreadable_files_count_as_no_limit(tmp_path):
    """A cgroup file that is not a number, a /proc without meminfo: no figure from them (None when none at all
    can be read is the caller's "no check")."""
    proc = fake_proc(tmp_path / "proc", "0::/\n")
    (proc / "meminfo").unlink()
    cg = tmp_path / "cgroup"
    files(cg, cgroup_controllers="memory\n", memory_max="lots\n", memory_current="0\n")
    limits = memory_limits(proc, cg)
    assert CGROUP_V2 not in limits


CHILD = """
import json, resource, sys
from pathlib import Path
from hybrid_sysid.core.memory import ADDRESS_SPACE, FREE, available_memory, memory_limits
def vmsize():
    return next(int(x.split()[1]) * 1024 for x in open("/proc/self/status") if x.startswith("VmSize:"))
limit = vmsize() + 2**30
resource.setrlimit(resource.RLIMIT_AS, (limit, resource.getrlimit(resource.RLIMIT_AS)[1]))
fake = memory_limits(Path(sys.argv[1]), Path(sys.argv[2]))
before = vmsize()
real = memory_limits()
after = vmsize()
print(json.dumps({"limit": limit, "fake": fake, "real": real.get(ADDRESS_SPACE), "before": before, "after": after,
                  "available": available_memory()}))
"""


def test_the_address_space_limit_a_child_sets_is_counted(tmp_path):
    """A child sets its soft RLIMIT_AS (what ulimit -v sets) 1 GiB above what it has mapped. With a fake /proc
    whose VmSize is 1000 kB, the figure is that limit less 1000 kB exactly; with the real one, the limit less the
    child's VmSize read around the call. Free memory (22 GiB on the test machine) no longer decides."""
    proc = fake_proc(tmp_path / "proc", "0::/\n", available_kib=64 * 2**20)
    empty = tmp_path / "no_cgroup"
    empty.mkdir()
    done = subprocess.run(
        [sys.executable, "-c", CHILD, str(proc), str(empty)], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    got = json.loads(done.stdout)
    assert got["fake"] == {FREE: 64 * GIB, ADDRESS_SPACE: got["limit"] - 1000 * 1024}
    assert got["limit"] - got["after"] <= got["real"] <= got["limit"] - got["before"]
    assert got["available"] <= got["limit"] - got["before"] and got["available"] <= 1.01 * GIB
