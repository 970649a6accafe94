"""LatchedReader: a latched topic's reader that is made again while its history never arrives.

Fast DDS's loss of a transient-local history to a late joiner cannot be provoked on demand, so
these tests lose it themselves: the first reader's deliveries are dropped (``_deliver`` of
the first subscription ignored), as a reader that DDS never serves.
"""

from rclpy.node import Node
from std_msgs.msg import String

from kilobot_twin.ros import qos
from kilobot_twin.ros.latched import LatchedReader

from ..nodes.graph import Graph


def drop_first_reader(monkeypatch, topic_suffix=""):
    """Deliveries to the first reader of every topic ending in ``topic_suffix`` are lost."""
    real = LatchedReader._deliver

    def deliver(self, made_at, msg):
        if made_at == 0 and self.topic.endswith(topic_suffix):
            return
        real(self, made_at, msg)

    monkeypatch.setattr(LatchedReader, "_deliver", deliver)


def test_a_reader_that_is_never_served_subscribes_again_and_hears_the_latched_message(monkeypatch):
    drop_first_reader(monkeypatch)
    with Graph() as g:
        pub_node = g.add(Node("writer", context=g.context))
        pub = pub_node.create_publisher(String, "/doc", qos.LATCHED)
        pub.publish(String(data="first"))
        node = g.add(Node("reader", context=g.context))
        got = []
        reader = LatchedReader(node, String, "/doc", lambda m: got.append(m.data), retry_s=0.6)
        g.spin_until(lambda: False, 0.4)
        assert got == [] and reader.retries == 0  # before retry_s: waiting
        assert g.spin_until(lambda: got, 5)
        assert got == ["first"] and reader.retries == 1 and reader.heard
        # Heard once: an ordinary subscription from then on, and nothing made again.
        pub.publish(String(data="second"))
        assert g.spin_until(lambda: len(got) == 2, 5)
        g.spin_until(lambda: False, 1.5)
        assert got == ["first", "second"] and reader.retries == 1


def test_a_reader_without_a_writer_is_not_made_again(monkeypatch):
    with Graph() as g:
        node = g.add(Node("reader", context=g.context))
        reader = LatchedReader(node, String, "/nobody", lambda m: None, retry_s=0.3)
        g.spin_until(lambda: False, 1.5)
        assert reader.retries == 0 and not reader.heard


def test_a_served_reader_is_not_made_again():
    with Graph() as g:
        pub_node = g.add(Node("writer", context=g.context))
        pub_node.create_publisher(String, "/doc", qos.LATCHED).publish(String(data="x"))
        node = g.add(Node("reader", context=g.context))
        got = []
        reader = LatchedReader(node, String, "/doc", lambda m: got.append(m.data), retry_s=0.3)
        assert g.spin_until(lambda: got, 5)
        g.spin_until(lambda: False, 1.0)
        assert got == ["x"] and reader.retries == 0



def test_no_node_reads_a_latched_topic_but_through_a_latched_reader():
    """Every subscription with qos.LATCHED in the package is a LatchedReader's own: a plain one
    would hang a run the day Fast DDS does not serve it (the CI failure of stop 57)."""
    import ast
    from pathlib import Path

    import kilobot_twin

    root = Path(kilobot_twin.__file__).parent
    plain = []
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call) and getattr(node.func, "attr", "") == "create_subscription":
                if any(isinstance(a, ast.Attribute) and a.attr == "LATCHED" for a in list(node.args) + [k.value for k in node.keywords]):
                    plain.append(f"{path.relative_to(root)}:{node.lineno}")
    assert [p.split(":")[0] for p in plain] == ["ros/latched.py"], plain
