"""How a JointCtlError names the value it refuses."""

from __future__ import annotations

from jointctl.errors import JointCtlError


def test_a_long_value_in_an_error_keeps_its_start_and_its_end():
    path = "/tmp/" + "a-long-folder/" * 10 + "nothere.xacro"
    text = str(JointCtlError("no such file", field="robot", value=path))
    assert "nothere.xacro" in text and "/tmp/a-long" in text and "..." in text
    assert len(text.split("(got ")[1]) <= 81  # the repr within 80 characters, and the closing parenthesis
