"""The shared command table and argument parsers."""

import pytest

from inspection_robot.command import (CommandError, CommandTable, parse_choice,
                                      parse_float, parse_int, parse_json, split_fields, success)


def test_dispatch_unknown_command_fails_with_its_name():
    reply = CommandTable({"go": lambda data: "went " + data}).dispatch("fly", "x")
    assert reply == ("failed", "unknown command 'fly'")


def test_an_unknown_name_is_echoed_capped_not_in_full():
    table = CommandTable({"go": lambda data: "went " + data})
    assert table.dispatch("x" * 100000, "") == ("failed", "unknown command '%s...'" % ("x" * 40))
    assert table.dispatch("y" * 40, "") == ("failed", "unknown command '%s'" % ("y" * 40))


def test_dispatch_success_and_command_error():
    def bad(_data):
        raise CommandError("angle out of range")
    table = CommandTable({"go": lambda data: "went " + data, "bad": bad, "reply": lambda d: success("r")})
    assert table.dispatch("go", "home") == ("success", "went home")
    assert table.dispatch("bad", "") == ("failed", "angle out of range")
    assert table.dispatch("reply", "") == ("success", "r")


@pytest.mark.parametrize("text", ["abc", "1.5", "", " 3", "0x10"])
def test_parse_int_rejects_junk(text):
    with pytest.raises(CommandError):
        parse_int(text, "speed")


@pytest.mark.parametrize("text", ["nan", "inf", "-inf", "1e400", "abc", ""])
def test_parse_float_rejects_non_finite_and_junk(text):
    with pytest.raises(CommandError):
        parse_float(text, "x")


def test_huge_numbers_are_refused_by_length_not_parsed():
    # str -> int is quadratic (no limit on Python 3.8): a megabyte of digits must not reach int()
    for parse in (parse_int, parse_float):
        with pytest.raises(CommandError, match="too long"):
            parse("9" * 1000000, "x")
    assert parse_int("-" + "0" * 40 + "5", "x") == -5


@pytest.mark.parametrize("text", ["not json", "[" * 100000 + "]" * 100000, None, ""])
def test_parse_json_turns_every_bad_input_into_a_command_error(text):
    with pytest.raises(CommandError, match="goal data is not valid JSON"):
        parse_json(text, "goal data")


@pytest.mark.parametrize("text,why", [
    ('{"x": NaN}', "x must be a finite number, got NaN"), ('[Infinity]', "data[0] must be a finite number, got "
                                                                         "Infinity"),
    ('{"a": {"b": [1, -Infinity]}}', "a.b[1] must be a finite number, got -Infinity"),
    ('{"x": 1e400}', "x must be a finite number, got 1e400"), ('-1e999', "data must be a finite number, got -1e999"),
    ('[%s]' % ("9" * 5000), "data is not valid JSON: a number of 5000 digits is too long"),
])
def test_parse_json_refuses_what_is_not_a_finite_number(text, why):
    with pytest.raises(CommandError) as err:
        parse_json(text)
    assert str(err.value) == why if "valid JSON" not in why else str(err.value).startswith(why)


def test_parse_json_keeps_ordinary_numbers():
    assert parse_json('{"a": 1.5e3, "b": -7, "c": 1e-300, "d": [%s]}' % ("9" * 64)) == {
        "a": 1500.0, "b": -7, "c": 1e-300, "d": [int("9" * 64)]}


def test_ranges():
    assert parse_int("-18000", "pan", -18000, 18000) == -18000
    with pytest.raises(CommandError, match="out of range"):
        parse_int("18001", "pan", -18000, 18000)
    assert parse_float("2.5", "x", 0, 3) == 2.5
    assert parse_choice("auto", "mode", ("auto", "manual")) == "auto"
    with pytest.raises(CommandError, match="auto|manual"):
        parse_choice("fast", "mode", ("auto", "manual"))


@pytest.mark.parametrize("data,count", [("1,2,3", 2), ("1,,2", 3), ("1, 2", 2), ("", 1)])
def test_split_fields_rejects_wrong_shapes(data, count):
    with pytest.raises(CommandError):
        split_fields(data, count)


def test_split_fields():
    assert split_fields("12300,-300", 2) == ["12300", "-300"]
