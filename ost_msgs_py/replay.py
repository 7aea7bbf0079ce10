"""A recording replayed (``ost replay``): its messages decoded and fed to the world's own
bookkeeping (:class:`~ost_ros.lockstep.follow.RunFollower`), and the rebuilt result compared with
the one the world published."""

from __future__ import annotations

import json
from dataclasses import dataclass

from ost_msgs_py import bag, wire
from ost_ros.lockstep.follow import FollowError, RunFollower, StepHook
from ost_ros.lockstep.messages import RunInfo
from ost_ros.model import Scenario
from ost_ros.result import RunResult


@dataclass
class Replayed:
    """A recording followed to its end: the rebuilt result and what the recording says."""

    follower: RunFollower
    result: RunResult
    recorded: dict | None  # the world's own result (``<ns>/result``), if recorded
    messages: int  # messages read
    namespace: str

    @property
    def scenario(self) -> Scenario:
        assert self.follower.scenario is not None
        return self.follower.scenario

    @property
    def matches(self) -> bool | None:
        """Whether the rebuilt result is the world's (None: the recording has no result)."""
        if self.recorded is None:
            return None
        return json.dumps(self.result.to_dict(), sort_keys=True) == json.dumps(self.recorded, sort_keys=True)


def replay(path: str, on_step: StepHook | None = None) -> Replayed:
    """Follow a recording (``ost_up.sh --record``) from its first message to its last."""
    follower = RunFollower(on_step=on_step)
    recorded, count, namespace = None, 0, ""
    for rec in bag.read(path):
        count += 1
        if rec.type_name == wire.type_name(RunInfo):
            namespace = rec.topic.rpartition("/")[0]
        if rec.type_name == "std_msgs/msg/String" and rec.topic.endswith("/result"):
            try:
                recorded = json.loads(bag.decode(rec).data)
            except ValueError:
                raise FollowError(f"{rec.topic}: the recorded result is not JSON") from None
            continue
        if not rec.type_name.startswith("ost_msgs/"):
            continue
        try:
            follower.feed(wire.from_cdr(rec.type_name, rec.data))
        except wire.MessageError as exc:
            follower.ignored += 1
            if follower.info is None and rec.type_name == wire.type_name(RunInfo):
                raise FollowError(f"{rec.topic}: {exc}") from None
    return Replayed(follower, follower.result(), recorded, count, namespace)
