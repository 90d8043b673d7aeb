"""The llm reader against a real local HTTP endpoint: structured output, validated."""

import json
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import ClassVar

import pytest

from tabletop.reader import ParseError
from tabletop.reader.llm import PLAN_SCHEMA, LLMReader, plan_from_json
from tabletop.reader.llm_client import LLMConfig
from tabletop.reader.plan import Between, Compass, Goal, GoTo, Part, Side


class Endpoint(BaseHTTPRequestHandler):
    replies: ClassVar[dict[str, str]] = {}
    seen: ClassVar[list[dict]] = []

    def do_POST(self):
        body = json.loads(self.rfile.read(int(self.headers["Content-Length"])))
        Endpoint.seen.append(body)
        content = Endpoint.replies[body["messages"][-1]["content"]]
        out = json.dumps({"choices": [{"message": {"content": content}}]}).encode()
        self.send_response(200)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(out)))
        self.end_headers()
        self.wfile.write(out)

    def log_message(self, *args):
        pass


@pytest.fixture(scope="module")
def reader():
    server = ThreadingHTTPServer(("127.0.0.1", 0), Endpoint)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    yield LLMReader(LLMConfig(f"http://127.0.0.1:{server.server_port}/v1", "test", timeout_s=5))
    server.shutdown()


def test_a_plan_comes_back_typed_and_the_schema_is_sent(reader):
    plan = {
        "steps": [
            {"action": "goto", "goal": {"primary": {"kind": "obj", "text": "red  mug"},
                                        "near": [{"kind": "sound", "text": "a dog barking"}]}},
            {"action": "side", "side": "left",
             "goal": {"primary": {"kind": "obj", "text": "duck"}}},
            {"action": "compass", "direction": "north", "distance_m": 0.05, "times": 2},
        ]
    }  # fmt: skip
    Endpoint.replies["mug by the dog, then left of the duck, then 5 cm north twice"] = (
        "Sure: " + json.dumps(plan)
    )
    r = reader.understand("mug by the dog, then left of the duck, then 5 cm north twice")
    assert [s.action for s in r.steps] == [
        GoTo(Goal(Part("obj", "red mug"), (Part("sound", "a dog barking"),))),
        Side("left", "duck"),
        Compass("north", 0.05),
    ]
    assert r.steps[2].times == 2 and r.reader == "llm"
    assert Endpoint.seen[-1]["response_format"]["json_schema"]["schema"] == PLAN_SCHEMA


@pytest.mark.parametrize(
    ("reply", "problem"),
    [
        ("I cannot help with that.", "no JSON object"),
        ('{"steps": []}', "no steps"),
        ('{"steps": [{"action": "teleport"}]}', "action must be one of"),
        ('{"steps": [{"action": "between", "a": {"primary": {"kind": "obj", "text": "x"}}}]}',
         "steps\\[0\\].b: missing"),
        ('{"steps": [{"action": "compass", "direction": "north", "distance_m": 40}]}',
         "distance_m"),
        ('{"steps": [{"action": "goto", "goal": {"primary": {"kind": "smell", "text": "x"}}}]}',
         "kind in"),
    ],
)  # fmt: skip
def test_an_invalid_plan_is_refused_with_its_problem(reply, problem):
    with pytest.raises(ParseError, match=problem):
        plan_from_json(reply, "some request")


def test_between_reads_both_goals():
    a = {"primary": {"kind": "obj", "text": "tray"}}
    b = {"primary": {"kind": "area", "text": "the far side"}}
    reply = json.dumps({"steps": [{"action": "between", "a": a, "b": b}]})
    (step,) = plan_from_json(reply, "r")
    assert step.action == Between(Goal(Part("obj", "tray")), Goal(Part("area", "the far side")))
