"""Signed messages in-process: keys on disk, sealing, and every way a receiver drops a message."""

import array
import stat

import ost_msgs.msg as ros
import pytest

from ost_msgs_py import auth, wire
from ost_ros.lockstep.messages import Acted, Sample, Tick
from ost_ros.messages import Action, ActionKind, Observation
from ost_ros.protocols.ccp.messages import Selection


@pytest.fixture(scope="module")
def keys(tmp_path_factory):
    d = tmp_path_factory.mktemp("keys")
    auth.make_keys(d, [0, 1, 2], run="abc123")
    return d


def signer(keys, who):
    return auth.Signer(auth.load_team(keys), who, auth.load_private(keys, who))


def selection(sender=0, run="abc123"):
    return wire.to_ros(Sample(Selection(sender, 3, 1, (4, 5)), 3, 0, run))


def test_key_files_are_private_and_the_team_file_public(keys):
    for name in ("world", "agent_0", "agent_1", "agent_2"):
        assert stat.S_IMODE((keys / f"{name}.key").stat().st_mode) == 0o600
        assert (keys / f"{name}.key").read_text().startswith("-----BEGIN PRIVATE KEY-----")
    assert stat.S_IMODE(keys.stat().st_mode) == 0o700
    team = auth.load_team(keys)
    assert team.run == "abc123" and sorted(team.keys) == [auth.WORLD, 0, 1, 2]


def test_a_genuine_message_passes_once(keys):
    v = auth.Verifier(auth.load_team(keys))
    m = signer(keys, 0).seal(selection(), "/ost/selection")
    assert v.check(m, "/ost/selection") is None
    assert v.check(m, "/ost/selection").startswith("replayed: counter")
    assert v.counts() == {"unsigned": 0, "forged": 0, "replayed": 1}


@pytest.mark.parametrize(
    "case, why",
    [
        ("unsigned", "unsigned: this run accepts signed messages only"),
        ("other topic", "forged: the signature does not match"),
        ("altered", "forged: the signature does not match"),
        ("other run", "forged: the signature does not match"),
        ("for another agent", "forged: signed by agent 1, sent as agent 0"),
        ("another's id", "forged: the signature does not match"),
        ("a tick by an agent", "forged: signed by agent 1, sent as the world"),
        ("unknown signer", "forged: agent 7 has no key in this run"),
        ("stranger's key", "forged: the signature does not match"),
    ],
)
def test_forgeries_are_dropped_with_the_reason(keys, case, why):
    team = auth.load_team(keys)
    v = auth.Verifier(team)
    topic = "/ost/selection"
    m = selection()
    if case == "unsigned":
        pass
    elif case == "other topic":
        signer(keys, 0).seal(m, "/ost/object_found")
    elif case == "altered":
        signer(keys, 0).seal(m, topic)
        m.objects = array.array("i", [9])
    elif case == "other run":
        auth.Signer(auth.Team("other", {}), 0, auth.load_private(keys, 0)).seal(m, topic)
    elif case == "for another agent":
        signer(keys, 1).seal(m, topic)  # agent 1's own key, a message "from agent 0"
    elif case == "another's id":
        auth.Signer(team, 0, auth.load_private(keys, 1)).seal(m, topic)
    elif case == "a tick by an agent":
        topic = "/ost/agent_0/tick"
        m = signer(keys, 1).seal(wire.to_ros(Tick(1, 0, Observation(0, 1, (0, 0)), run="abc123")), topic)
    elif case == "unknown signer":
        m = signer(keys, 0).seal(selection(7), topic)
        m.auth.signer = 7
    elif case == "stranger's key":
        auth.Signer(team, 0, auth.Ed25519PrivateKey.generate()).seal(m, topic)
    assert v.check(m, topic).startswith(why)


def test_every_publish_is_a_new_counter_and_old_counters_are_refused(keys):
    s, v = signer(keys, 0), auth.Verifier(auth.load_team(keys))
    m = selection()
    first = s.seal(m, "/ost/selection").auth.counter
    assert v.check(m, "/ost/selection") is None
    s.seal(m, "/ost/selection")  # published again (a resend): a fresh counter, accepted
    assert m.auth.counter == first + 1 and v.check(m, "/ost/selection") is None
    # out of order within the window: fine; a counter the window has passed: refused
    late = signer(keys, 1)
    late.counter = 10**6
    a = late.seal(selection(1), "/ost/selection")
    b = late.seal(selection(1), "/ost/selection")
    assert v.check(b, "/ost/selection") is None and v.check(a, "/ost/selection") is None
    late.counter += auth.WINDOW
    c = late.seal(selection(1), "/ost/selection")
    late.counter -= 2 * auth.WINDOW
    old = late.seal(selection(1), "/ost/selection")
    assert v.check(c, "/ost/selection") is None
    assert v.check(old, "/ost/selection").startswith("replayed")


def test_the_signed_bytes_cover_every_field_and_not_auth():
    a = wire.to_ros(Acted(Action(2, 5, ActionKind.MOVE, (1, 0)), 1, run="r"))
    b = wire.to_ros(Acted(Action(2, 5, ActionKind.MOVE, (0, 1)), 1, run="r"))
    assert auth.canonical(a) != auth.canonical(b)
    before = auth.canonical(a)
    a.auth.signer, a.auth.counter, a.auth.signature = 2, 7, array.array("B", b"x" * 64)
    assert auth.canonical(a) == before
    assert auth.claimed_signer(a) == 2 and auth.claimed_signer(ros.RunEnd()) == auth.WORLD


def test_bad_key_material_is_one_line(tmp_path, keys):
    with pytest.raises(auth.AuthError, match=r"team\.yaml: cannot read"):
        auth.load_team(tmp_path)
    (tmp_path / "team.yaml").write_text("run: x\nworld: zz\nagents: {0: aa}\n")
    with pytest.raises(auth.AuthError, match="world: not an Ed25519 public key"):
        auth.load_team(tmp_path)
    (tmp_path / "agent_0.key").write_text("nonsense")
    (tmp_path / "agent_0.key").chmod(0o600)
    with pytest.raises(auth.AuthError, match=r"agent_0\.key: not a PEM private key"):
        auth.load_private(tmp_path, 0)


def test_signatures_are_plain_ed25519_whichever_library_makes_or_checks_them(keys):
    """Sealing and checking go through libsodium (PyNaCl) for speed; the signature is the same
    deterministic Ed25519 one OpenSSL (cryptography) makes, and either one's checks the other's."""
    team = auth.load_team(keys)
    key = auth.load_private(keys, 0)
    m = signer(keys, 0).seal(selection(), "/ost/selection")
    data = auth.signed_bytes(team.run, "/ost/selection", m, 0, m.auth.counter)
    assert bytes(m.auth.signature) == key.sign(data)
    team.keys[0].verify(bytes(m.auth.signature), data)  # OpenSSL accepts libsodium's
    other = selection()
    other.auth.signer, other.auth.counter = 0, m.auth.counter + 1
    other_data = auth.signed_bytes(team.run, "/ost/selection", other, 0, other.auth.counter)
    other.auth.signature = array.array("B", key.sign(other_data))
    assert auth.Verifier(team).check(other, "/ost/selection") is None  # libsodium accepts OpenSSL's
    bad = array.array("B", bytes(other.auth.signature))
    bad[0] ^= 1
    other.auth.signature = bad
    assert auth.Verifier(team).check(other, "/ost/selection").startswith("forged: the signature")


def test_a_signature_of_the_wrong_length_is_forged(keys):
    m = signer(keys, 0).seal(selection(), "/ost/selection")
    m.auth.signature = array.array("B", bytes(m.auth.signature)[:10])
    assert auth.Verifier(auth.load_team(keys)).check(m, "/ost/selection").startswith("forged: ")
