"""worm_model.bags.topic_names against rclpy's validate_full_topic_name (rmw's rules, code we did not write): the
same names refused, drawn by hypothesis from the characters and shapes that matter."""
from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st
from rclpy.exceptions import InvalidTopicNameException
from rclpy.validate_full_topic_name import validate_full_topic_name

from worm_model.bags.topic_names import MAX_LENGTH, topic_name_problem


def rclpy_refuses(name: str) -> bool:
    try:
        validate_full_topic_name(name)
    except InvalidTopicNameException:
        return True
    return False


NAMES = st.one_of(
    st.text(alphabet="ab_1/ -~{}.Z", min_size=1, max_size=12).map(lambda s: "/" + s),
    st.integers(MAX_LENGTH - 2, MAX_LENGTH + 2).map(lambda n: "/" + "a" * (n - 1)),
)


@settings(max_examples=400, deadline=None)
@given(NAMES)
def test_the_same_names_as_rclpy(name: str) -> None:
    assert (topic_name_problem(name) is not None) == rclpy_refuses(name), (name, topic_name_problem(name))


def test_a_relative_name_is_taken_from_the_root() -> None:
    assert topic_name_problem("rig/sample") is None
    assert topic_name_problem("not a topic") == "it holds ' ': only letters, digits, '_' and '/' are allowed"
