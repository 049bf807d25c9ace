"""Facts about the machine a report was generated on, shared by the report scripts."""
import platform


def cpu_model():
    """The CPU's model name from /proc/cpuinfo, else what Python knows, else 'unknown'."""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"
