"""Sealed messages in-process: keys on disk, pairwise keys, sealing, and every way a receiver drops
a message — through a node's receive path (``ost_ros.node.transport.Receiver``) on the bytes DDS
would carry."""

import stat

import pytest
from cryptography.hazmat.primitives.asymmetric.x25519 import X25519PrivateKey

from ost_msgs_py import auth, wire
from ost_ros.lockstep.messages import Sample, Tick
from ost_ros.messages import Observation
from ost_ros.node import transport as tp
from ost_ros.node.signing import NodeAuth
from ost_ros.protocols.ccp.messages import Selection

TOPIC = "/ost/selection"


@pytest.fixture(scope="module")
def keys(tmp_path_factory):
    d = tmp_path_factory.mktemp("keys")
    auth.make_keys(d, [0, 1, 2], run="abc123")
    return d


def member(keys, who, team=None, key=None) -> auth.Keys:
    """``who``'s pairwise keys (another team file's, or another private key, if given)."""
    return auth.Keys(team or auth.load_team(keys), who, key or auth.load_private(keys, who))


def sealed(k: auth.Keys, value, topic=TOPIC, receivers=None, counter=None) -> bytes:
    s = auth.Sealer(k, start=counter)
    data = wire.to_cdr(value, counter=s.next(), signer=s.signer, tags=s.size)
    s.seal(data, topic, receivers)
    return bytes(data)


def selection(sender=0, run="abc123"):
    return Sample(Selection(sender, 3, 1, (4, 5)), 3, 0, run)


class Log:
    def __init__(self):
        self.lines: list[str] = []

    def warning(self, text: str) -> None:
        self.lines.append(text)


def receiver(keys, who, kind=Selection, topic=TOPIC, skip=None):
    """``who``'s receive path for ``kind`` on ``topic``: (receive, its log, its NodeAuth)."""
    guard = NodeAuth(member(keys, who))
    log = Log()
    r = tp.Receiver(kind, lambda v: None, guard, tp.Throttle(log), skip=skip)
    r.topic = topic
    return r, log, guard


def test_key_files_are_private_and_the_team_file_public(keys):
    ids = {"world": auth.WORLD, "membership": auth.MEMBERSHIP, "agent_0": 0, "agent_1": 1, "agent_2": 2}
    for name, signer in ids.items():
        assert stat.S_IMODE((keys / f"{name}.key").stat().st_mode) == 0o600
        assert (keys / f"{name}.key").read_text().startswith("-----BEGIN PRIVATE KEY-----")
        assert isinstance(auth.load_private(keys, signer), X25519PrivateKey)
    assert stat.S_IMODE(keys.stat().st_mode) == 0o700
    team = auth.load_team(keys)
    assert team.run == "abc123" and sorted(team.keys) == [auth.MEMBERSHIP, auth.WORLD, 0, 1, 2]
    # the tag vector's slots: the world, the membership monitor, the robots
    assert team.members == (auth.WORLD, auth.MEMBERSHIP, 0, 1, 2)


def test_a_pairwise_key_is_the_two_members_and_one_direction(keys):
    """K(s→r) is computed alike by s and r, by nobody else, and differs from K(r→s) and from
    the same pair's key in another run."""
    team = auth.load_team(keys)
    shared = auth.load_private(keys, 0).exchange(team.keys[1])
    assert shared == auth.load_private(keys, 1).exchange(team.keys[0])
    k01 = auth.pair_key(shared, "abc123", 0, 1)
    assert k01 != auth.pair_key(shared, "abc123", 1, 0) != auth.pair_key(shared, "other", 0, 1)
    a, b = member(keys, 0), member(keys, 1)
    tag = a.send[1].copy()
    tag.update(b"digest")
    other = b.receive[0].copy()
    other.update(b"digest")
    assert tag.digest() == other.digest()
    assert auth.Sealer(a).size == 5 * auth.TAG  # the world, the membership monitor, three agents


def test_a_genuine_message_passes_once_at_every_receiver(keys):
    data = sealed(member(keys, 0), selection())
    for who in (auth.WORLD, 0, 1, 2):
        recv, log, guard = receiver(keys, who)
        got = recv.receive(data)
        assert got == selection() and not log.lines
        assert recv.receive(data) is None
        assert log.lines == [f"dropped message on {TOPIC} from agent 0: replayed: counter {data_counter(data)} "
                             "of agent 0 seen before"]  # fmt: skip
        assert guard.counts() == {"unsigned": 0, "forged": 0, "replayed": 1, "malformed": 0, "stale": 0}


def data_counter(data: bytes) -> int:
    return auth.trailer(data, 5 * auth.TAG)[0]


@pytest.mark.parametrize(
    "case, why",
    [
        ("unsigned", "unsigned: this run accepts sealed messages only"),
        ("other topic", "forged: the tag does not match"),
        ("altered", "forged: the tag does not match"),
        ("tag altered", "forged: the tag does not match"),
        ("other run", "forged: the tag does not match"),
        ("for another agent", "forged: sealed by agent 1, sent as agent 0"),
        ("another's id", "forged: the tag does not match"),
        ("a tick by an agent", "forged: sealed by agent 1, sent as the world"),
        ("unknown signer", "forged: agent 7 has no key in this run"),
        ("stranger's key", "forged: the tag does not match"),
        ("another team's size", "forged: no tag vector of this team's size (5 members)"),
        ("sealed for another", "forged: no tag for agent 2 (sealed for other receivers)"),
        ("truncated", "forged: no tag vector of this team's size"),
        ("extended", "forged: no tag vector of this team's size"),
    ],
)
def test_forgeries_are_dropped_with_the_reason(tmp_path, keys, case, why):
    """What the receiver (agent 2) says of each, with the sender the message claims."""
    team = auth.load_team(keys)
    topic, kind, claimed = TOPIC, Selection, "agent 0"
    k0 = member(keys, 0)
    if case == "unsigned":
        data = bytes(wire.to_cdr(selection()))
    elif case == "other topic":
        data = sealed(k0, selection(), topic="/ost/object_found")
    elif case in ("altered", "tag altered"):
        data = bytearray(sealed(k0, selection()))
        data[-auth.TAG + 5 if case == "tag altered" else -5 * auth.TAG - 40] ^= 1  # agent 2's tag; the body
        data = bytes(data)
    elif case == "other run":
        data = sealed(member(keys, 0, auth.Team("other", team.keys)), selection())
    elif case == "for another agent":
        data = sealed(member(keys, 1), selection())  # agent 1's own keys, a message "from agent 0"
    elif case == "another's id":  # agent 1's private key, sealing as agent 0
        data = sealed(member(keys, 0, key=auth.load_private(keys, 1)), selection())
    elif case == "a tick by an agent":
        topic, kind, claimed = "/ost/agent_2/tick", Tick, "the world"
        data = sealed(member(keys, 1), Tick(1, 0, Observation(2, 1, (0, 0)), run="abc123"), topic)
    elif case == "unknown signer":
        sealer = auth.Sealer(k0)
        data = wire.to_cdr(selection(7), counter=sealer.next(), signer=7, tags=sealer.size)
        sealer.seal(data, topic)
        data, claimed = bytes(data), "agent 7"
    elif case == "stranger's key":
        data = sealed(member(keys, 0, key=X25519PrivateKey.generate()), selection())
    elif case == "another team's size":
        other = tmp_path / "other"
        auth.make_keys(other, [0, 1], run="abc123")
        data = sealed(member(other, 0), selection())
    elif case == "sealed for another":
        data = sealed(k0, selection(), receivers=(1,))
    elif case == "truncated":
        data, claimed = sealed(k0, selection())[:-7], "unknown"  # (nor can it be read)
    elif case == "extended":
        data = sealed(k0, selection()) + b"\1\2\3\4"
    recv, log, guard = receiver(keys, 2, kind, topic)
    assert recv.receive(data) is None
    assert len(log.lines) == 1 and log.lines[0].startswith(
        f"dropped message on {topic} from {claimed}: {why}"
    )
    assert sum(guard.counts().values()) == 1


def test_whoever_holds_a_robots_key_can_forge_only_to_that_robot(keys):
    """The one promise MACs give up (docs/ros.md, threat model): agent 1's key computes every key
    agent 1 shares — K(2→1) too — so agent 1 can be made to accept a message in agent 2's name;
    agent 0 and the world cannot, whatever the holder puts in their slots."""
    team, stolen = auth.load_team(keys), auth.load_private(keys, 1)
    # In agent 2's name: for agent 1 the right key (X25519 is symmetric), for everyone else the
    # best the holder has — its own keys with them, under agent 2's id.
    as_2 = auth.Keys(team, 2, stolen)
    s = auth.Sealer(as_2)
    data = wire.to_cdr(selection(2), counter=s.next(), signer=2, tags=s.size)
    s.seal(data, TOPIC)
    slot1 = 3 * auth.TAG  # (the world, the membership monitor, agent 0, agent 1, agent 2)
    k21 = auth.pair_key(stolen.exchange(team.keys[2]), "abc123", 2, 1)
    start = len(data) - s.size
    data[start + slot1 : start + slot1 + auth.TAG] = auth.tag(k21, auth.digest(TOPIC, data[:start]))
    data = bytes(data)
    for who in (auth.WORLD, 0):
        recv, log, _ = receiver(keys, who)
        assert recv.receive(data) is None
        assert "from agent 2: forged: the tag does not match" in log.lines[0]
    recv, log, _ = receiver(keys, 1)
    assert recv.receive(data) == selection(2)  # given up: A's key speaks to A in anyone's name


def test_a_dead_robots_original_relayed_by_another_verifies_everywhere(keys):
    """Agent 2 seals for everyone and dies; the world (or any process, keys or none) relays its
    bytes as received: every receiver accepts them — once."""
    original = sealed(member(keys, 2), selection(2))

    class Pub:
        def __init__(self):
            self.sent: list[bytes] = []

        def publish(self, data: bytes) -> None:
            self.sent.append(data)

    pub = Pub()
    NodeAuth().relay(pub, original)  # no keys needed to relay
    NodeAuth(member(keys, auth.WORLD)).relay(pub, original)
    assert pub.sent == [original, original]
    for who in (auth.WORLD, 0, 1):
        recv, log, _ = receiver(keys, who)
        assert recv.receive(pub.sent[0]) == selection(2) and not log.lines
        assert recv.receive(pub.sent[1]) is None and "replayed" in log.lines[0]


def test_a_message_for_one_receiver_is_sealed_for_it_alone(keys):
    tick = Tick(1, 0, Observation(0, 1, (0, 0)), run="abc123")
    data = sealed(member(keys, auth.WORLD), tick, "/ost/agent_0/tick", receivers=(0,))
    tags = data[-5 * auth.TAG :]
    # slots: the world, the membership monitor, agent 0 (the only tag), agents 1 and 2
    assert tags[: 2 * auth.TAG] == bytes(2 * auth.TAG) and tags[3 * auth.TAG :] == bytes(2 * auth.TAG)
    recv, log, _ = receiver(keys, 0, Tick, "/ost/agent_0/tick")
    assert recv.receive(data) == tick and not log.lines


def test_skipped_messages_are_neither_counted_nor_marked(keys):
    """A node's own test for copies it holds comes before the replay window (a relayed original
    carries its first counter): a skipped message is not a replay, and not seen either."""
    data = sealed(member(keys, 0), selection())
    skipping = [True]
    recv, log, guard = receiver(keys, 1, skip=lambda m: skipping[0])
    assert recv.receive(data) is None and not log.lines and sum(guard.counts().values()) == 0
    skipping[0] = False
    assert recv.receive(data) == selection()
    # a stranger's forgery is dropped before the node's test sees it
    recv2, _, guard2 = receiver(keys, 1, skip=lambda m: True)
    assert recv2.receive(bytes(wire.to_cdr(selection()))) is None and guard2.counts()["unsigned"] == 1


def test_every_publish_is_a_new_counter_and_old_counters_are_refused(keys):
    c = auth.Checker(member(keys, 1))
    assert c.fresh(0, 10) is None and c.fresh(0, 10).startswith("replayed: counter 10 of agent 0")
    assert c.fresh(0, 12) is None and c.fresh(0, 11) is None  # out of order within the window: fine
    assert c.fresh(auth.WORLD, 10) is None  # each signer its own window
    high = 10**6
    assert c.fresh(0, high) is None
    assert c.fresh(0, high - auth.WINDOW + 1) is None
    assert c.fresh(0, high - auth.WINDOW).startswith("replayed")  # the window has passed it
    s = auth.Sealer(member(keys, 0))
    assert s.next() + 1 == s.next()  # every message its own counter


def test_the_replay_window_stays_bounded():
    w = auth.Window()
    for c in range(0, 5 * auth.WINDOW, 1):
        assert w.fresh(c)
        assert len(w.seen) < auth.Window.PRUNE_AT
    assert not w.fresh(5 * auth.WINDOW - 1) and not w.fresh(4 * auth.WINDOW - 1)
    assert w.fresh(10**12) and not w.fresh(10**12 - auth.WINDOW)  # a restart far above: fine


def test_the_tags_cover_every_byte_before_them(keys):
    data = sealed(member(keys, 0), selection())
    checker = auth.Checker(member(keys, 1))
    start = len(data) - checker.size
    for k in range(4, start):  # the header aside (not covered by CDR readers either)
        bad = bytearray(data)
        bad[k] ^= 0x80
        assert checker.check(bytes(bad), TOPIC) is not None, k
    other_slot = bytearray(data)
    other_slot[start] ^= 1  # the world's tag: not agent 1's business
    assert checker.check(bytes(other_slot), TOPIC) is None


def test_an_insecure_node_sends_no_tags_and_checks_nothing(keys):
    class Pub:
        topic_name = TOPIC

        def publish(self, data):
            self.data = data

    pub = Pub()
    NodeAuth().publish(pub, selection())
    assert pub.data.endswith(b"\0\0\0\0")  # an empty tag vector
    r = tp.Receiver(Selection, lambda v: None, NodeAuth(), tp.Throttle(Log()))
    assert r.receive(pub.data) == selection()
    recv, log, _ = receiver(keys, 0)
    assert recv.receive(pub.data) is None and "unsigned" in log.lines[0]


def test_bad_key_material_is_one_line(tmp_path, keys):
    with pytest.raises(auth.AuthError, match=r"team\.yaml: cannot read"):
        auth.load_team(tmp_path)
    (tmp_path / "team.yaml").write_text("run: x\nworld: zz\nagents: {0: aa}\n")
    with pytest.raises(auth.AuthError, match="world: not an X25519 public key"):
        auth.load_team(tmp_path)
    (tmp_path / "team.yaml").write_text("run: x\nagents: {0: aa}\n")
    with pytest.raises(auth.AuthError, match="world: not an X25519 public key"):
        auth.load_team(tmp_path)
    (tmp_path / "agent_0.key").write_text("nonsense")
    (tmp_path / "agent_0.key").chmod(0o600)
    with pytest.raises(auth.AuthError, match=r"agent_0\.key: not a PEM private key"):
        auth.load_private(tmp_path, 0)
    from cryptography.hazmat.primitives import serialization
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

    old = Ed25519PrivateKey.generate().private_bytes(
        serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption()
    )
    (tmp_path / "agent_0.key").write_bytes(old)  # a key of the signatures' days
    with pytest.raises(auth.AuthError, match=r"agent_0\.key: not an X25519 key"):
        auth.load_private(tmp_path, 0)
    team = auth.load_team(keys)
    low = dict(team.keys)
    low[2] = auth.X25519PublicKey.from_public_bytes(bytes(32))  # a low-order point: no secret
    with pytest.raises(auth.AuthError, match="agent 2: not a usable X25519 public key"):
        auth.Keys(auth.Team(team.run, low), 0, auth.load_private(keys, 0))
    with pytest.raises(auth.AuthError, match="no key for agent 5"):
        auth.Keys(team, 5, auth.load_private(keys, 0))


def test_a_claimed_sender_is_read_from_any_message():
    msg = wire.decode(Selection, bytes(wire.to_cdr(selection(2))))[0]
    assert auth.claimed_signer(msg) == 2
    tick = wire.decode(Tick, bytes(wire.to_cdr(Tick(1, 0, Observation(0, 1, (0, 0))))))[0]
    assert auth.claimed_signer(tick) == auth.WORLD
