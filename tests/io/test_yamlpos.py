"""Tests for hybridteam.io.yamlpos: values, exact positions, and located errors.

Expected values and marks are written by hand from the inline documents (lines counted from 1),
never computed with the code under test.
"""

from __future__ import annotations

import math
import pickle
import textwrap
from pathlib import Path as FsPath

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hybridteam.io.yamlpos import Mark, SourceError, format_path, load_yaml


def doc(text: str) -> str:
    return textwrap.dedent(text).lstrip("\n")


def error_of(source: object, **kwargs: object) -> SourceError:
    with pytest.raises(SourceError) as info:
        load_yaml(source, **kwargs)  # type: ignore[arg-type]
    return info.value


# --- values ------------------------------------------------------------------------------


def test_yaml_1_1_booleans_stay_strings_and_numbers_follow_yaml_1_2() -> None:
    text = doc("""
        on: yes
        off: no
        flags: [y, n, Y, N, On, OFF]
        bools: [true, True, TRUE, false, False, FALSE]
        floats: [1e-6, 1E3, -2.5e+3, .5, 5., 3.25, +1.0]
        ints: [0, 7, -3, +4, 007]
        special: [.inf, -.inf, +.inf, .Inf]
        nulls: [~, null, Null, NULL]
        empty:
        odd: [0x1F, 1_000, 12:30, 0o17, 1.2.3, e5, .]
        quoted: ["true", '1e-6', "null"]
    """)
    data, _ = load_yaml(text)
    assert data["on"] == "yes"
    assert data["off"] == "no"
    assert data["flags"] == ["y", "n", "Y", "N", "On", "OFF"]
    assert data["bools"] == [True, True, True, False, False, False]
    assert all(type(b) is bool for b in data["bools"])
    assert data["floats"] == [1e-6, 1000.0, -2500.0, 0.5, 5.0, 3.25, 1.0]
    assert all(type(x) is float for x in data["floats"])
    assert data["ints"] == [0, 7, -3, 4, 7]
    assert all(type(x) is int for x in data["ints"])
    assert data["special"] == [math.inf, -math.inf, math.inf, math.inf]
    assert data["nulls"] == [None, None, None, None]
    assert data["empty"] is None
    assert data["odd"] == ["0x1F", "1_000", "12:30", "0o17", "1.2.3", "e5", "."]
    assert data["quoted"] == ["true", "1e-6", "null"]


def test_nan_and_explicit_standard_tags() -> None:
    data, _ = load_yaml("a: .nan\nb: !!str 5\nc: !!float 3\nd: !!int '42'\ne: !!bool true\n")
    assert math.isnan(data["a"])
    assert data["b"] == "5"
    assert data["c"] == 3.0 and type(data["c"]) is float
    assert data["d"] == 42
    assert data["e"] is True


def test_block_scalars_anchors_and_flow_values() -> None:
    text = doc("""
        lit: |
          one
            two
        fold: >-
          a
          b
        base: &b {x: 1}
        copy: *b
    """)
    data, _ = load_yaml(text)
    assert data == {
        "lit": "one\n  two\n",
        "fold": "a b",
        "base": {"x": 1},
        "copy": {"x": 1},
    }


# --- positions ---------------------------------------------------------------------------


NESTED = doc("""
    # comment line
    agents:
      ball:
        modes:
          - name: fall
            guard: h <= 0
          - name: bounce
            on: [{to: fall, guard: "v > 0"}]
    flow: {a: 1, b: [2, 3]}
""")
#   line 1  "# comment line"
#   line 2  "agents:"
#   line 3  "  ball:"
#   line 4  "    modes:"
#   line 5  "      - name: fall"
#   line 6  "        guard: h <= 0"
#   line 7  "      - name: bounce"
#   line 8  "        on: [{to: fall, guard: \"v > 0\"}]"
#   line 9  "flow: {a: 1, b: [2, 3]}"


def test_marks_of_keys_and_values_in_block_style() -> None:
    _, pos = load_yaml(NESTED)
    assert pos.key(("agents",)) == Mark(2, 1)
    assert pos.value(("agents",)) == Mark(3, 3)
    assert pos.key(("agents", "ball")) == Mark(3, 3)
    assert pos.value(("agents", "ball", "modes")) == Mark(5, 7)
    assert pos.value(("agents", "ball", "modes", 0)) == Mark(5, 9)
    assert pos.key(("agents", "ball", "modes", 0, "name")) == Mark(5, 9)
    assert pos.value(("agents", "ball", "modes", 0, "name")) == Mark(5, 15)
    assert pos.key(("agents", "ball", "modes", 0, "guard")) == Mark(6, 9)
    assert pos.value(("agents", "ball", "modes", 0, "guard")) == Mark(6, 16)
    assert pos.value(("agents", "ball", "modes", 1)) == Mark(7, 9)
    # list items have no key
    assert pos.key(("agents", "ball", "modes", 1)) is None


def test_marks_in_flow_style() -> None:
    _, pos = load_yaml(NESTED)
    on = ("agents", "ball", "modes", 1, "on")
    assert pos.value(on) == Mark(8, 13)
    assert pos.value((*on, 0)) == Mark(8, 14)
    assert pos.key((*on, 0, "to")) == Mark(8, 15)
    assert pos.value((*on, 0, "to")) == Mark(8, 19)
    assert pos.key((*on, 0, "guard")) == Mark(8, 25)
    assert pos.value((*on, 0, "guard")) == Mark(8, 32)
    assert pos.value(("flow",)) == Mark(9, 7)
    assert pos.key(("flow", "a")) == Mark(9, 8)
    assert pos.value(("flow", "a")) == Mark(9, 11)
    assert pos.key(("flow", "b")) == Mark(9, 14)
    assert pos.value(("flow", "b")) == Mark(9, 17)
    assert pos.value(("flow", "b", 0)) == Mark(9, 18)
    assert pos.value(("flow", "b", 1)) == Mark(9, 21)


def test_unknown_paths_and_nearest() -> None:
    _, pos = load_yaml(NESTED)
    assert pos.value(("agents", "nope")) is None
    assert pos.key(("flow", "b", 7)) is None
    assert pos.nearest(("agents", "ball", "modes", 0, "missing", 3)) == (
        ("agents", "ball", "modes", 0),
        Mark(5, 9),
    )
    assert pos.nearest(("elsewhere",)) == ((), Mark(1, 1))  # the root is the whole file
    assert pos.value(()) == Mark(1, 1)


def test_marks_of_block_scalars_and_crlf_line_endings() -> None:
    text = "a: 1\r\nlit: |\r\n  x\r\n  y\r\nb: two\r\n"
    data, pos = load_yaml(text)
    assert data == {"a": 1, "lit": "x\ny\n", "b": "two"}
    assert pos.value(("lit",)) == Mark(2, 6)
    assert pos.key(("b",)) == Mark(5, 1)
    assert pos.value(("b",)) == Mark(5, 4)


def test_utf8_bom_does_not_shift_columns() -> None:
    data, pos = load_yaml(b"\xef\xbb\xbfname: caf\xc3\xa9\nx: 1\n")
    assert data == {"name": "café", "x": 1}
    assert pos.key(("name",)) == Mark(1, 1)
    assert pos.value(("x",)) == Mark(2, 4)


# --- in_scalar -----------------------------------------------------------------------------


def test_in_scalar_plain_and_quoted() -> None:
    text = doc("""
        plain: h <= 0 and vv < 0
        guard: "h <= 0 and vv < 0"
        single: 'it''s vv'
        escaped: "a\\tb vv"
        tagged: &g !!str h and vv
        list: [x, "p vv"]
    """)
    data, pos = load_yaml(text)
    assert data["single"] == "it's vv"
    assert data["escaped"] == "a\tb vv"
    # column where "vv" starts, counted by hand in the document above
    assert pos.in_scalar(("plain",), data["plain"].index("vv")) == Mark(1, 19)
    assert pos.in_scalar(("guard",), data["guard"].index("vv")) == Mark(2, 20)
    assert pos.in_scalar(("guard",), 0) == Mark(2, 9)
    assert pos.in_scalar(("single",), data["single"].index("vv")) == Mark(3, 16)
    assert pos.in_scalar(("single",), 3) == Mark(3, 14)  # the "s" after the doubled quote
    assert pos.in_scalar(("escaped",), data["escaped"].index("vv")) == Mark(4, 16)
    assert pos.in_scalar(("escaped",), 2) == Mark(4, 14)  # the "b" after "\t"
    assert pos.in_scalar(("tagged",), data["tagged"].index("vv")) == Mark(5, 24)
    assert pos.in_scalar(("list", 1), 2) == Mark(6, 14)
    # one past the end is allowed (e.g. "unexpected end of expression"); beyond is not
    assert pos.in_scalar(("plain",), len(data["plain"])) == Mark(1, 25)
    assert pos.in_scalar(("plain",), len(data["plain"]) + 1) is None
    assert pos.in_scalar(("list",), 0) is None  # not a scalar
    assert pos.in_scalar(("nope",), 0) is None


def test_in_scalar_block_and_multiline() -> None:
    text = doc("""
        lit: |
          first line
            vv indented
          last vv
        fold: >
          a b
          c vv
        plain: one
          two vv
        dq: "one
          two vv"
    """)
    data, pos = load_yaml(text)
    assert data["lit"] == "first line\n  vv indented\nlast vv\n"
    assert pos.in_scalar(("lit",), 0) == Mark(2, 3)
    assert pos.in_scalar(("lit",), data["lit"].index("vv")) == Mark(3, 5)
    assert pos.in_scalar(("lit",), data["lit"].rindex("vv")) == Mark(4, 8)
    assert data["fold"] == "a b c vv\n"
    assert pos.in_scalar(("fold",), data["fold"].index("vv")) == Mark(7, 5)
    assert data["plain"] == "one two vv"
    assert pos.in_scalar(("plain",), data["plain"].index("vv")) == Mark(9, 7)
    assert data["dq"] == "one two vv"
    assert pos.in_scalar(("dq",), data["dq"].index("vv")) == Mark(11, 7)


# --- errors ----------------------------------------------------------------------------------


def test_source_error_formatting_and_pickling() -> None:
    err = SourceError("m.yaml", 3, 7, ("agents", "ball", "modes", 2, "guard"), "bad")
    assert str(err) == "m.yaml:3:7: agents.ball.modes[2].guard: bad"
    assert (err.file, err.line, err.column, err.message) == ("m.yaml", 3, 7, "bad")
    assert str(SourceError("m.yaml", message="file is empty")) == "m.yaml: file is empty"
    assert str(SourceError("m.yaml", 4, None, (), "x")) == "m.yaml:4: x"
    assert format_path(("a b", 0, "x.y", "ok")) == "['a b'][0]['x.y'].ok"
    again = pickle.loads(pickle.dumps(err))
    assert str(again) == str(err) and again.path == err.path


def test_positions_error_helper_points_at_key_or_value() -> None:
    _, pos = load_yaml("a:\n  b: 1\n", filename="f.yaml")
    assert str(pos.error(("a", "b"), "nope")) == "f.yaml:2:6: a.b: nope"
    assert str(pos.error(("a", "b"), "nope", at_key=True)) == "f.yaml:2:3: a.b: nope"
    assert str(pos.error(("a", "zz"), "gone")) == "f.yaml:2:3: a.zz: gone"


def test_duplicate_key_reported_at_second_occurrence() -> None:
    text = doc("""
        mode:
          to: a
          guard: x
          reset: y
          guard: z
    """)
    err = error_of(text, filename="m.yaml")
    assert (err.file, err.line, err.column) == ("m.yaml", 5, 3)
    assert err.path == ("mode", "guard")
    assert err.message == "duplicate key 'guard' (first at line 3)"


@pytest.mark.parametrize(
    ("text", "shown"),
    [("1: x\n", "1"), ("true: x\n", "true"), ("~: x\n", "~"), ("[a]: x\n", "a list")],
)
def test_non_string_keys_are_rejected(text: str, shown: str) -> None:
    err = error_of(text)
    assert (err.line, err.column) == (1, 1)
    assert err.message.startswith(f"mapping keys must be names, got {shown}")


def test_quoted_number_key_is_fine() -> None:
    assert load_yaml('"1": x\non: y\n')[0] == {"1": "x", "on": "y"}


def test_merge_keys_are_rejected_clearly() -> None:
    err = error_of("base: &b {x: 1}\nother:\n  <<: *b\n")
    assert (err.line, err.column) == (3, 3)
    assert "merge keys" in err.message


@pytest.mark.parametrize(
    ("text", "line", "column", "message"),
    [
        # line 2 lacks a colon; PyYAML notices at the start of line 3
        ("a: 1\nb\nc: 2\n", 3, 1, "could not find expected ':'"),
        ("a: 1\n  b: 2\n", 2, 4, "mapping values are not allowed here"),
        ("a: 'abc\nb: 2\n", 3, 1, "found unexpected end of stream"),
        ("a:\n  - 1\n  - [2, 3\nb: 4\n", 4, 2, "expected ',' or ']', but got ':'"),
        ("a:\n\tb: 1\n", 2, 1, "found character '\\t' that cannot start any token"),
        ("a: 1\n---\nb: 2\n", 2, 1, "expected a single document"),
        ("a: *nope\n", 1, 4, "found undefined alias 'nope'"),
        ("a: &x 1\nb: &x 2\n", 2, 4, "duplicate anchor '&x' (first at line 1)"),
    ],
)
def test_syntax_errors_are_located(text: str, line: int, column: int, message: str) -> None:
    err = error_of(text, filename="s.yaml")
    assert (err.file, err.line, err.column) == ("s.yaml", line, column)
    assert err.message.startswith(message)


def test_syntax_error_mentions_where_the_construct_started() -> None:
    err = error_of("a: 1\nb\nc: 2\n")
    assert "line 2, column 1" in err.message


@pytest.mark.parametrize("text", ["", "\n\n", "# only a comment\n  # another\n", "---\n"])
def test_empty_files(text: str) -> None:
    err = error_of(text, filename="e.yaml")
    assert str(err) == "e.yaml:1:1: file is empty (no document in it)"


@pytest.mark.parametrize(
    ("text", "kind"),
    [("- a\n- b\n", "a list"), ("just text\n", "a string"), ("42\n", "a number"), ("~\n", "null")],
)
def test_top_level_must_be_a_mapping(text: str, kind: str) -> None:
    err = error_of(text)
    assert (err.line, err.column) == (1, 1)
    assert err.message == f"expected a mapping of keys at the top level, got {kind}"


def test_binary_and_badly_encoded_input() -> None:
    err = error_of(b"a: 1\nname: caf\xe9\n", filename="l1.yaml")  # Latin-1 'é'
    assert (err.line, err.column) == (2, 10)
    assert err.message == "not a text file (invalid UTF-8 at byte 14)"
    err = error_of(b"\x89PNG\r\n\x1a\n\x00\x00")
    assert (err.line, err.message) == (1, "not a text file (invalid UTF-8 at byte 0)")
    err = error_of(b"a: 1\nb: x\x00y\n")
    assert (err.line, err.column) == (2, 5)
    assert err.message.startswith("not a text file")
    err = error_of("a: 1\n\x00")
    assert (err.line, err.column) == (2, 1)
    err = error_of("a: b\x07c\n")
    assert (err.line, err.column) == (1, 5)
    assert "U+0007" in err.message
    assert "UTF-16" in error_of("a: 1\n".encode("utf-16")).message


def test_files_by_path(tmp_path: FsPath) -> None:
    good = tmp_path / "team.yaml"
    good.write_text("a:\n  b: [1, 2]\n", encoding="utf-8")
    data, pos = load_yaml(good)
    assert data == {"a": {"b": [1, 2]}}
    assert pos.filename == str(good)
    bad = tmp_path / "bad.yaml"
    bad.write_text("a: 1\na: 2\n", encoding="utf-8")
    assert str(error_of(bad)).startswith(f"{bad}:2:1: a: duplicate key 'a'")
    assert error_of(bad, filename="shown.yaml").file == "shown.yaml"
    missing = error_of(tmp_path / "missing.yaml")
    assert missing.file == str(tmp_path / "missing.yaml") and missing.line is None
    assert missing.message.startswith("cannot read file: ")
    assert error_of(tmp_path).message.startswith("cannot read file: ")


@pytest.mark.parametrize(
    ("text", "line", "column", "tag"),
    [
        ("a: !!python/object/apply:os.system ['echo hi']\n", 1, 4, "!!python/object/apply"),
        ("a: 1\nb: !!python/name:os.system ''\n", 2, 4, "!!python/name"),
        ("x:\n  y: !custom 3\n", 2, 6, "!custom"),
        ("a: !!set {x, y}\n", 1, 4, "!!set"),
        ("a: !!binary aGk=\n", 1, 4, "!!binary"),
    ],
)
def test_unsupported_tags_are_rejected(text: str, line: int, column: int, tag: str) -> None:
    err = error_of(text)
    assert (err.line, err.column) == (line, column)
    assert err.message.startswith(f"tag {tag}")
    assert "not supported" in err.message


def test_bad_value_for_explicit_tag() -> None:
    err = error_of("a: !!int 1.5\n")
    assert (err.line, err.column, err.message) == (1, 4, "'1.5' is not a valid !!int")


def test_alias_bomb_is_stopped() -> None:
    lines = ["a: &a [x, x, x, x, x, x, x, x, x, x]"]
    for i in range(1, 9):
        prev, cur = chr(ord("a") + i - 1), chr(ord("a") + i)
        lines.append(f"{cur}: &{cur} [" + ", ".join([f"*{prev}"] * 10) + "]")
    err = error_of("\n".join(lines) + "\n")
    assert "more than 100000 values" in err.message
    assert err.line is not None and 2 <= err.line <= 9


def test_moderate_aliases_are_fine() -> None:
    data, pos = load_yaml("a: &a [1, 2]\nb: [*a, *a]\n")
    assert data["b"] == [[1, 2], [1, 2]]
    assert pos.value(("b", 1, 0)) == Mark(1, 8)  # expanded values point at their definition


def test_recursive_alias_is_rejected() -> None:
    err = error_of("a: &a\n  - 1\n  - *a\n")
    assert (err.line, err.column) == (3, 5)
    assert "recursive" in err.message


def test_deep_nesting_is_rejected() -> None:
    err = error_of("a: " + "[" * 500 + "]" * 500 + "\n")
    assert err.line == 1 and "nested too deeply" in err.message


# --- robustness ----------------------------------------------------------------------------

VALID = doc("""
    # a small team, ~30 lines
    name: demo
    agents:
      ball: &ball
        kind: unicycle
        speed: 1.5e-1
        modes:
          - name: fall
            flow: {x: v, v: -9.81}
            on:
              - to: bounce
                guard: "h <= 0 and v < 0"
                reset: 'v: -0.8 * v'
          - name: bounce
            invariant: |
              h >= 0
              v <= 10
            note: >
              folded text
              continues
      copy: *ball
    network:
      loss: 0.1
      delay: [1, 2, .5, 5., .inf]
      enabled: true
      mode: on
      tag: !!str 5
      nothing: ~
      items:
      - a
      - {b: c, d: [e, f]}
""")
MUTATION_CHARS = [*" \n\t:-[]{},#&*!|>'\"?%@`.~09az\\", "\x00", "\x85", "é", "\ufeff", "\r"]


def check_loads_or_source_error(source: str | bytes) -> None:
    try:
        data, pos = load_yaml(source)
    except SourceError as err:
        assert str(err)
        return
    assert isinstance(data, dict)
    stack: list[tuple[tuple[str | int, ...], object]] = [((), data)]
    while stack:
        path, value = stack.pop()
        assert pos.nearest(path)[0] == path
        if isinstance(value, str):
            for offset in range(len(value) + 1):
                pos.in_scalar(path, offset)
        elif isinstance(value, dict):
            stack.extend(((*path, k), v) for k, v in value.items())
        elif isinstance(value, list):
            stack.extend(((*path, i), v) for i, v in enumerate(value))


def test_valid_document_loads() -> None:
    data, _ = load_yaml(VALID)
    assert data["agents"]["copy"] == data["agents"]["ball"]
    assert data["network"]["mode"] == "on" and data["network"]["tag"] == "5"


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.binary(max_size=200))
def test_random_bytes_only_raise_source_error(raw: bytes) -> None:
    check_loads_or_source_error(raw)


@settings(max_examples=500, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.lists(
        st.tuples(
            st.sampled_from(["delete", "insert", "replace"]),
            st.integers(min_value=0, max_value=len(VALID)),
            st.sampled_from(MUTATION_CHARS),
        ),
        min_size=1,
        max_size=3,
    ),
    st.booleans(),
)
def test_mutated_documents_only_raise_source_error(
    edits: list[tuple[str, int, str]], as_bytes: bool
) -> None:
    text = VALID
    for op, where, char in edits:
        where = min(where, len(text))
        if op == "delete":
            text = text[:where] + text[where + 1 :]
        elif op == "insert":
            text = text[:where] + char + text[where:]
        else:
            text = text[:where] + char + text[where + 1 :]
    check_loads_or_source_error(text.encode("utf-8") if as_bytes else text)
