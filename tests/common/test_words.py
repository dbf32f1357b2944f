import pytest

from common.words import listed


@pytest.mark.parametrize(("words", "expected"), [
    ([], ""),
    (["track"], "track"),
    (["track", "jig J1"], "track and jig J1"),
    (["ball_run", "wave", "a_in"], "ball_run, wave and a_in"),
    (iter(["a", "b", "c", "d"]), "a, b, c and d"),
])
def test_listed_names_a_list_as_a_sentence(words, expected):
    assert listed(words) == expected
