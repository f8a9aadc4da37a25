"""A benchmark suite file (configs/bench/*.toml), read and checked: a syntax
error, a missing or misspelt key, or a value of the wrong kind is one line
naming the file and the key, not a traceback or a silently ignored setting."""
import tomllib

# Every key a suite may hold, by table, and the type of its value.
NUM = (int, float)
TOP = {"description": str, "osg": dict, "report": str, "run": dict, "scales": dict, "targets": dict}
OSG = {"min_vertices": int, "occlusion": str, "query_frame_count": int, "visibility_threshold": int}
RUN = {"client_timeout": NUM, "clients": list, "compress": str, "cost": str, "lp_num_threads": int,
       "osg_baseline": bool, "query_thresholds": list, "sweep_clients": int, "repeats": int,
       "link_gbps": NUM}
TARGETS = {"efficiency": dict, "max_over_mean": NUM, "speedup_4": NUM}
SCALE = {"frames": int, "height": int, "width": int, "osg_baseline": bool, "path_frames": int,
         "path_start": int, "reference_stride": int, "scenes": list}
SCALE_REQUIRED = ("width", "height", "scenes")
SCENE = {"name": str, "kind": str, "of": str, "copies": int, "triangles": int, "geodes": int, "path": str,
         "seed": int, "frames": int, "path_frames": int, "path_start": int}


class SuiteError(Exception):
    pass


def _check_table(table, schema, where, path):
    if not isinstance(table, dict):
        raise SuiteError(f"{path}: {where} must be a table")
    for key, value in table.items():
        if key not in schema:
            raise SuiteError(f"{path}: {where + '.' if where else ''}{key}: unknown key "
                             f"(known: {', '.join(sorted(schema))})")
        want = schema[key]
        if isinstance(value, bool) and want is not bool and bool not in (want if isinstance(want, tuple) else (want,)):
            ok = False
        else:
            ok = isinstance(value, want)
        if not ok:
            names = want.__name__ if isinstance(want, type) else " or ".join(t.__name__ for t in want)
            raise SuiteError(f"{path}: {where + '.' if where else ''}{key}: expected {names}, "
                             f"got {type(value).__name__} {value!r}")


def check_suite(suite, path):
    """Raises SuiteError naming `path` and the first key that is wrong."""
    _check_table(suite, TOP, "", path)
    for name, schema in (("osg", OSG), ("run", RUN), ("targets", TARGETS)):
        if name in suite:
            _check_table(suite[name], schema, name, path)
    scales = suite.get("scales")
    if not scales:
        raise SuiteError(f"{path}: no [scales] table")
    for scale, cfg in scales.items():
        where = f"scales.{scale}"
        _check_table(cfg, SCALE, where, path)
        for key in SCALE_REQUIRED:
            if key not in cfg:
                raise SuiteError(f"{path}: {where}: missing {key}")
        for i, sc in enumerate(cfg["scenes"]):
            _check_table(sc, SCENE, f"{where}.scenes[{i}]", path)
            if "name" not in sc:
                raise SuiteError(f"{path}: {where}.scenes[{i}]: missing name")
            if sc.get("kind", "replicate") == "replicate" and not ("of" in sc and "copies" in sc):
                raise SuiteError(f"{path}: {where}.scenes[{i}] ({sc['name']}): a replicate scene needs of and copies")


def load_suite(path):
    """The suite at `path` (a pathlib.Path), checked; raises SuiteError."""
    try:
        suite = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as e:
        raise SuiteError(f"{path}: not valid TOML: {e}") from None
    except OSError as e:
        raise SuiteError(f"{path}: cannot read: {e.strerror}") from None
    check_suite(suite, path)
    return suite
