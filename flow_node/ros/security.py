"""Is the node really secured when ROS 2 security (SROS2) is asked for? The start-up check behind its warning.

With ``ROS_SECURITY_ENABLE=true`` rcl looks the node's enclave up in ``ROS_SECURITY_KEYSTORE``. Under the
Enforce strategy a missing enclave or a middleware without DDS-Security stops the node at start-up, but under
Permissive (also the default when ``ROS_SECURITY_STRATEGY`` is unset) a missing enclave, or one without all its
security files, makes the middleware run **with no security at all**, silently. And the Fast DDS of the
ros-jazzy wheels on the package registry has no DDS-Security (built with ``HAVE_SECURITY 0``): with an
enclave it refuses to start, without one it runs unsecured. :func:`assess` finds these cases from what can be
known in the process (docs/security.md lists what cannot); :func:`check_node` gathers the facts for a node.

The functions below :func:`check_node` are plain Python over plain values, for the unit tests.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

from ..middleware import FAST_DDS_RMWS

# rmw_dds_common::get_security_files: an enclave needs all of these (the key and certificate may be PKCS#11
# URIs in key.p11 / cert.p11 instead of PEM files).
SECURITY_FILES: tuple[tuple[str, ...], ...] = (("identity_ca.cert.pem",), ("cert.pem", "cert.p11"),
                                               ("key.pem", "key.p11"), ("permissions_ca.cert.pem",),
                                               ("governance.p7s",), ("permissions.p7s",))
# rmw_fastrtps_shared_cpp carries this message only when built without DDS-Security (#if HAVE_SECURITY ... #else)
FASTDDS_NO_SECURITY_MARK = b"doesn't have the security libraries"
# RMWs that apply SROS2 enclaves through DDS-Security when their DDS has it
DDS_SECURITY_RMWS = (*FAST_DDS_RMWS, "rmw_cyclonedds_cpp", "rmw_connextdds")


@dataclass(frozen=True)
class SecuritySettings:
    """The SROS2 environment of the process (rcl reads it at ``rclpy.init``)."""

    enabled: bool  # ROS_SECURITY_ENABLE is exactly "true" (rcl's test)
    enforce: bool  # ROS_SECURITY_STRATEGY is "Enforce"; anything else is Permissive
    keystore: str  # ROS_SECURITY_KEYSTORE, "" if unset
    enclave_override: str  # ROS_SECURITY_ENCLAVE_OVERRIDE, "" if unset


@dataclass(frozen=True)
class SecurityCheck:
    """The verdict: ``secured`` is True (as far as can be checked), False (certainly not) or None (security
    not asked for); ``problems`` are one-line reasons, ``details`` the facts (for diagnostics)."""

    secured: bool | None
    problems: tuple[str, ...]
    details: tuple[tuple[str, str], ...]

    @property
    def summary(self) -> str:
        if self.secured is None:
            return "security not enabled"
        if self.problems:
            return "ROS_SECURITY_ENABLE=true but the node runs UNSECURED: " + "; ".join(self.problems)
        return "secured (SROS2)"


def settings_from_env(env: Mapping[str, str]) -> SecuritySettings:
    """The SROS2 variables of ``env`` (e.g. ``os.environ``)."""
    return SecuritySettings(enabled=env.get("ROS_SECURITY_ENABLE", "") == "true",
                            enforce=env.get("ROS_SECURITY_STRATEGY", "") == "Enforce",
                            keystore=env.get("ROS_SECURITY_KEYSTORE", ""),
                            enclave_override=env.get("ROS_SECURITY_ENCLAVE_OVERRIDE", ""))


def enclave_dir(keystore: str, enclave: str, override: str = "") -> Path:
    """The directory rcl uses for ``enclave`` (or for ``ROS_SECURITY_ENCLAVE_OVERRIDE`` when set):
    ``<keystore>/enclaves/<enclave without its leading />`` (``/`` is ``<keystore>/enclaves`` itself)."""
    name = (override or enclave or "/").strip("/")
    root = Path(keystore) / "enclaves"
    return root / name if name else root


def missing_files(directory: Path, exists: Callable[[Path], bool] = Path.is_file) -> list[str]:
    """The security files (:data:`SECURITY_FILES`) the enclave ``directory`` lacks, by their PEM name."""
    return [names[0] for names in SECURITY_FILES if not any(exists(directory / n) for n in names)]


def rmw_has_security(rmw: str, rmw_libraries: Iterable[bytes]) -> bool | None:
    """Whether the middleware ``rmw`` can apply DDS-Security: False for a Fast DDS RMW whose loaded
    libraries carry :data:`FASTDDS_NO_SECURITY_MARK` (the ros-jazzy wheels), True for the other DDS RMWs,
    None for an RMW this check does not know (e.g. rmw_zenoh_cpp, which does not use SROS2 enclaves)."""
    if rmw not in DDS_SECURITY_RMWS:
        return None
    if rmw in FAST_DDS_RMWS and any(FASTDDS_NO_SECURITY_MARK in lib for lib in rmw_libraries):
        return False
    return True


def assess(settings: SecuritySettings, enclave: str, rmw: str, rmw_security: bool | None,
           missing: list[str] | None) -> SecurityCheck:
    """The verdict for a running node: its SROS2 ``settings``, its ``enclave`` (as the graph reports it),
    its ``rmw`` and whether that can do security (:func:`rmw_has_security`), and the security files its
    enclave directory lacks (None: the directory does not exist)."""
    if not settings.enabled:
        return SecurityCheck(None, (), ())
    where = str(enclave_dir(settings.keystore, enclave, settings.enclave_override)) if settings.keystore else ""
    details = (("enclave", enclave or "/"), ("enclave override", settings.enclave_override or "none"),
               ("rmw", rmw), ("strategy", "Enforce" if settings.enforce else "Permissive"),
               ("keystore", settings.keystore or "unset"), ("enclave directory", where or "n/a"))
    problems = []
    if rmw_security is False:
        problems.append(f"{rmw} here is built without DDS-Security (the ros-jazzy wheels' Fast DDS; "
                        "use a system ROS 2 or Cyclone DDS with its security plugins: docs/security.md)")
    elif rmw_security is None:
        problems.append(f"{rmw} does not apply SROS2 enclaves (DDS-Security) as far as this check knows")
    if not settings.keystore:
        problems.append("ROS_SECURITY_KEYSTORE is not set")
    elif missing is None:
        problems.append(f"enclave {enclave or '/'} not found (no directory {where}); start the node with "
                        "--ros-args --enclave ENCLAVE and create it with ros2 security create_enclave")
    elif missing:
        problems.append(f"enclave directory {where} lacks {', '.join(missing)}")
    if problems and not settings.enforce:
        problems.append("the Permissive strategy let it start anyway: set ROS_SECURITY_STRATEGY=Enforce")
    return SecurityCheck(not problems, tuple(problems), details)


def loaded_libraries(prefixes: tuple[str, ...], maps: str = "/proc/self/maps") -> list[Path]:
    """Shared libraries mapped into this process whose file name starts with one of ``prefixes`` (Linux;
    empty elsewhere)."""
    try:
        text = Path(maps).read_text()
    except OSError:
        return []
    paths = {line.split(None, 5)[5].strip() for line in text.splitlines() if len(line.split(None, 5)) == 6}
    return sorted(Path(p) for p in paths if Path(p).name.startswith(prefixes))


def check_node(node: object) -> SecurityCheck:
    """:func:`assess` for an rclpy ``node`` of this process: its enclave from the ROS graph (its own entry),
    the RMW identifier, the RMW libraries it loaded, the enclave directory and the environment."""
    from rclpy.utilities import get_rmw_implementation_identifier

    settings = settings_from_env(os.environ)
    if not settings.enabled:
        return SecurityCheck(None, (), ())
    me = (node.get_name(), node.get_namespace())  # type: ignore[attr-defined]
    enclaves = [e for n, ns, e in node.get_node_names_and_namespaces_with_enclaves()  # type: ignore[attr-defined]
                if (n, ns) == me]
    enclave = enclaves[0] if enclaves else "/"
    rmw = get_rmw_implementation_identifier()
    libs = (p.read_bytes() for p in loaded_libraries(("librmw_fastrtps",)))
    where = enclave_dir(settings.keystore, enclave, settings.enclave_override)
    missing = missing_files(where) if settings.keystore and where.is_dir() else None
    return assess(settings, enclave, rmw, rmw_has_security(rmw, libs), missing)


def check_and_log(node: object) -> SecurityCheck:
    """:func:`check_node`, logged once at start-up: a warning per problem, else one info line."""
    check = check_node(node)
    log = node.get_logger()  # type: ignore[attr-defined]
    if check.problems:
        log.warning(check.summary)
    elif check.secured:
        log.info(f"{check.summary}: " + ", ".join(f"{k} {v}" for k, v in check.details))
    return check


def statuses(check: SecurityCheck, node_name: str, hardware_id: str) -> list[DiagnosticStatus]:
    """The node's security DiagnosticStatus ("<node>: security"): WARN with the problems, OK when secured
    as far as can be checked; none when security is not enabled."""
    if check.secured is None:
        return []
    level = DiagnosticStatus.OK if check.secured else DiagnosticStatus.WARN
    return [DiagnosticStatus(level=level, name=f"{node_name}: security", message=check.summary,
                             hardware_id=hardware_id, values=[KeyValue(key=k, value=v) for k, v in check.details])]
