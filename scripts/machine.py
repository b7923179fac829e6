"""The processor's model name, for the benchmark scripts' records of the machine they ran on."""


def cpu_model():
    """The 'model name' line of /proc/cpuinfo ('unknown cpu' where there is none)."""
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return "unknown cpu"
