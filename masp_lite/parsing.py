"""The one ``KEY=VALUE`` parser of every command's ``--set`` (no ``eval``).

:func:`parse_sets` splits ``KEY=VALUE`` strings among named targets (scenario overrides,
method options, training settings) and converts each value by the type of the field it
sets (:func:`field_types` of a dataclass: ``int``, ``float``, ``bool`` as ``true``/``false``,
``str``, ``X | None`` with ``none``, tuples as comma lists).
"""
import dataclasses
import types
import typing

__all__ = ["parse_value", "parse_sets", "field_types"]


def field_types(cls) -> dict[str, object]:
    """``{field name: type}`` of a dataclass; a field that is itself a dataclass gives its own fields instead
    (:class:`~masp_lite.config.TrainConfig`'s parts: ``lr``, not ``ppo``, as ``--set`` names them)."""
    hints = typing.get_type_hints(cls)
    out = {}
    for f in dataclasses.fields(cls):
        typ = hints[f.name]
        out.update(field_types(typ) if dataclasses.is_dataclass(typ) else {f.name: typ})
    return out


def _guess(text: str):
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    return parse_value(text, bool) if text.lower() in ("true", "false") else \
        None if text.lower() in ("none", "null") else text


def parse_value(text: str, typ=None):
    """Convert one ``--set`` value to ``typ``; without a type: int, float, bool, none, else str.

    >>> parse_value("none", int | None) is None, parse_value("3", float), parse_value("1,2", tuple[int, ...])
    (True, 3.0, (1, 2))
    """
    text = text.strip()
    if typ is None or typ is typing.Any:
        return _guess(text)
    args = typing.get_args(typ)
    if isinstance(typ, types.UnionType) or typing.get_origin(typ) is typing.Union:
        if type(None) in args and text.lower() in ("none", "null"):
            return None
        rest = [a for a in args if a is not type(None)]
        for a in rest:
            try:
                return parse_value(text, a)
            except ValueError:
                pass
        raise ValueError(f"expected {' or '.join(getattr(a, '__name__', str(a)) for a in args)}, got {text!r}")
    if typing.get_origin(typ) is tuple:
        items = [t for t in text.strip("()").split(",") if t.strip()]
        inner = args[0] if args else None
        return tuple(parse_value(t, inner) for t in items)
    if typ is bool:
        if text.lower() not in ("true", "false"):
            raise ValueError(f"expected true or false, got {text!r}")
        return text.lower() == "true"
    if typ is int:
        try:
            return int(text)  # exact, however large: 9007199254740993 is not rounded through a float
        except ValueError:
            pass
        try:
            f = float(text)
        except ValueError:
            raise ValueError(f"expected an int, got {text!r}") from None
        if not f.is_integer():
            raise ValueError(f"expected an int, got {text!r}")
        return int(f)
    if typ is float:
        try:
            return float(text)
        except ValueError:
            raise ValueError(f"expected a number, got {text!r}") from None
    if typ is str:
        return text
    raise ValueError(f"cannot parse a value of type {typ!r}")


def parse_sets(items, targets: dict[str, dict[str, object]]) -> dict[str, dict]:
    """Split ``KEY=VALUE`` strings among named targets and convert each value by its type.

    ``targets``: ``{target name: {key: type or None}}``, e.g. ``{"scenario override":
    {"num_agents": int, ...}, "training setting": field_types(TrainConfig)}``; a key goes
    to the first target that has it. Returns ``{target name: {key: value}}``. A string
    without ``=``, an unknown key or a value of the wrong type is one clear error that
    lists what is accepted.
    """
    out = {name: {} for name in targets}
    for item in items or []:
        key, sep, text = str(item).partition("=")
        key = key.strip()
        if not sep or not key:
            raise ValueError(f"--set {item!r}: expected KEY=VALUE")
        for name, keys in targets.items():
            if key in keys:
                try:
                    out[name][key] = parse_value(text, keys[key])
                except ValueError as e:
                    raise ValueError(f"--set {key}={text!r}: {e}") from None
                break
        else:
            known = "; ".join(f"{name}s {sorted(keys)}" for name, keys in targets.items())
            raise ValueError(f"--set {key}: unknown; expected one of the {known}")
    return out
