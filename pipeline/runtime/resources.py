"""What the machine gives a command, checked before any work: the memory a new allocation can
have (the system's, ``ulimit -v``'s, the cgroup's) and the free space on the output disks. Every
memory or disk refusal is one line naming the estimate and what there is (an OptionError)."""

import os

from ..errors import OptionError


def available_memory():
    """Bytes of memory a new allocation can have, or None where unknown: the least of what the
    system has available (MemAvailable), what the process's address-space limit leaves
    (RLIMIT_AS, ``ulimit -v``: beyond it an allocation fails) and what its cgroup's memory limit
    leaves (a container's or a batch job's: beyond it the process is killed)."""
    known = [left for left in (_system_available(), _address_space_left(), _cgroup_left()) if left is not None]
    return max(0, min(known)) if known else None


def _system_available():
    try:
        with open("/proc/meminfo") as meminfo:
            for row in meminfo:
                if row.startswith("MemAvailable:"):
                    return int(row.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def _address_space_left():
    """RLIMIT_AS less the address space the process maps now, or None without a limit."""
    try:
        import resource

        limit = resource.getrlimit(resource.RLIMIT_AS)[0]
        if limit == resource.RLIM_INFINITY:
            return None
        with open("/proc/self/statm") as statm:
            mapped = int(statm.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
        return limit - mapped
    except (ImportError, OSError, ValueError, IndexError):
        return None


def _cgroup_left():
    """The memory limit of this process's cgroup (v2 memory.max, v1 memory.limit_in_bytes) less
    what the group uses but could not give back (its inactive file cache counts as free), or None
    without a limit."""
    try:
        with open("/proc/self/cgroup") as groups:
            rows = [row.strip().split(":", 2) for row in groups if row.count(":") >= 2]
    except OSError:
        return None
    for _, controllers, path in rows:
        if controllers == "":  # v2
            root, files = "/sys/fs/cgroup", ("memory.max", "memory.current", "inactive_file")
        elif "memory" in controllers.split(","):  # v1
            root, files = "/sys/fs/cgroup/memory", ("memory.limit_in_bytes", "memory.usage_in_bytes",
                                                    "total_inactive_file")
        else:
            continue
        # the group's folder, or the mount's root where the namespace shows the group as its root
        for folder in (root + path.rstrip("/"), root):
            try:
                with open(os.path.join(folder, files[0])) as limit_file:
                    limit = limit_file.read().strip()
                if limit == "max" or int(limit) >= 2 ** 60:
                    break  # no limit at this group
                with open(os.path.join(folder, files[1])) as usage_file:
                    used = int(usage_file.read())
                inactive = 0
                with open(os.path.join(folder, "memory.stat")) as stat:
                    for row in stat:
                        name, _, value = row.partition(" ")
                        if name == files[2]:
                            inactive = int(value)
                return int(limit) - (used - inactive)
            except (OSError, ValueError):
                continue
    return None


def check_memory(needed, what, available=None):
    """Refuse, before allocating, a request whose arrays (``needed`` bytes, an estimate from its
    shapes) exceed the memory available (or ``available`` bytes): one line naming the sizes."""
    available = available_memory() if available is None else available
    if available is not None and needed > available:
        raise OptionError(f"{what} needs about {_size(needed)} of memory, and {_size(available)} is available: "
                          "ask for fewer")


def check_space(what, needs):
    """Refuse, before any work, a request whose outputs would not fit on their disks: ``needs``
    [(label, bytes, folder)], the folders (or, where one does not exist yet, the nearest folder
    above it that does) on one file system adding up against its free space. One line naming
    the estimate, the folder and its free space (and each part, when several share it)."""
    import shutil

    disks = {}
    for label, needed, folder in needs:
        there = os.path.abspath(folder)
        while not os.path.isdir(there) and os.path.dirname(there) != there:
            there = os.path.dirname(there)
        disks.setdefault(os.stat(there).st_dev, []).append((label, needed, folder, there))
    for parts in disks.values():
        needed, folder = sum(part[1] for part in parts), parts[0][2]
        free = shutil.disk_usage(parts[0][3]).free
        if needed > free:
            detail = "" if len(parts) == 1 else \
                " (" + ", ".join(f"{label} {_size(n)} in {where}" for label, n, where, _ in parts) + ")"
            raise OptionError(f"not enough space: {what} needs about {_size(needed)} of disk in {folder}{detail}, and "
                              f"{_size(free)} is free; nothing written: ask for fewer, or write elsewhere")


def _size(count):
    """Bytes as people read them: GiB from one GiB up, MiB below (a 64 MB disk is not "0.0 GiB")."""
    return f"{count / 2 ** 30:.1f} GiB" if count >= 2 ** 30 else f"{count / 2 ** 20:.1f} MiB"
