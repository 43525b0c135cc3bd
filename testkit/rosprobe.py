"""A rospy node that tests drive over stdin/stdout, one JSON request per line.

rospy binds a process to one master for its whole life, while every test
module gets a master of its own; so the test process itself never calls
`rospy.init_node`. It starts this probe instead, against its module's master,
and asks it to subscribe, publish, call services and look up transforms.

Requests and answers are JSON objects; messages travel as plain dicts (times
and durations as float seconds, byte arrays as lists of ints).
"""
import json
import sys
import threading
import time

import genpy
import roslib.message
import rospy
import rosservice
import tf2_ros

MAX_BUFFERED_MESSAGES = 2000


def to_plain(value):
    """Convert a ROS message (or field value) into JSON-friendly Python values."""
    if isinstance(value, (genpy.Time, genpy.Duration)):
        return value.to_sec()
    if isinstance(value, genpy.Message):
        return {slot: to_plain(getattr(value, slot)) for slot in value.__slots__}
    if isinstance(value, bytes):
        return list(value)
    if isinstance(value, (list, tuple)):
        return [to_plain(item) for item in value]
    return value


def message_class(type_name):
    cls = roslib.message.get_message_class(type_name)
    if cls is None:
        raise ValueError(f"unknown message type {type_name}")
    return cls


def filled(cls, fields):
    message = cls()
    if fields:
        genpy.message.fill_message_args(message, [fields])
    return message


class Probe:
    def __init__(self):
        self._lock = threading.Lock()
        self._buffers = {}
        self._counts = {}
        self._subscribers = {}
        self._publishers = {}
        self._tf_buffer = None

    def subscribe(self, topic, type):
        if topic not in self._subscribers:
            with self._lock:
                self._buffers[topic] = []
                self._counts[topic] = 0
            self._subscribers[topic] = rospy.Subscriber(
                topic, message_class(type), self._receive, callback_args=topic, queue_size=100)
        return {}

    def _receive(self, message, topic):
        entry = {"t": time.time(), "msg": to_plain(message)}
        with self._lock:
            buffer = self._buffers[topic]
            buffer.append(entry)
            self._counts[topic] += 1
            if len(buffer) > MAX_BUFFERED_MESSAGES:
                del buffer[: len(buffer) - MAX_BUFFERED_MESSAGES]

    def messages(self, topic, start=0):
        """Messages with index >= start (indices count every message ever received)."""
        with self._lock:
            buffer = self._buffers.get(topic, [])
            count = self._counts.get(topic, 0)
            first_index = count - len(buffer)
            selected = buffer[max(0, start - first_index):]
        return {"messages": selected, "count": count}

    def publish(self, topic, type, msg=None, latch=False, wait_for_subscribers=2.0):
        publisher = self._publishers.get(topic)
        if publisher is None:
            publisher = rospy.Publisher(topic, message_class(type), queue_size=100, latch=latch)
            self._publishers[topic] = publisher
            deadline = time.time() + wait_for_subscribers
            while publisher.get_num_connections() == 0 and time.time() < deadline:
                time.sleep(0.02)
        publisher.publish(filled(message_class(type), msg))
        return {"subscribers": publisher.get_num_connections()}

    def call(self, service, request=None, timeout=5.0):
        rospy.wait_for_service(service, timeout=timeout)
        service_class = rosservice.get_service_class_by_name(service)
        proxy = rospy.ServiceProxy(service, service_class)
        response = proxy(filled(service_class._request_class, request))
        return {"response": to_plain(response)}

    def transform(self, target, source, timeout=5.0):
        if self._tf_buffer is None:
            self._tf_buffer = tf2_ros.Buffer()
            self._listener = tf2_ros.TransformListener(self._tf_buffer)
        stamped = self._tf_buffer.lookup_transform(target, source, rospy.Time(0), rospy.Duration(timeout))
        return {"transform": to_plain(stamped)}

    def now(self):
        return {"time": rospy.get_time()}


def serve(probe, requests, replies):
    for line in requests:
        request = json.loads(line)
        operation = request.pop("op")
        try:
            answer = getattr(probe, operation)(**request)
            answer["ok"] = True
        except Exception as error:  # every failure goes back to the test; the probe lives on
            answer = {"ok": False, "error": f"{type(error).__name__}: {error}"}
        replies.write(json.dumps(answer) + "\n")
        replies.flush()


def main():
    # The reply channel is the real stdout, kept aside before rospy starts: rospy
    # prints to stdout (e.g. "Unable to immediately register with master node"
    # while a master restarts), which would corrupt the replies.
    replies = sys.stdout
    sys.stdout = sys.stderr
    rospy.init_node("test_probe", anonymous=True, disable_signals=True)
    replies.write(json.dumps({"ok": True, "ready": True}) + "\n")
    replies.flush()
    serve(Probe(), sys.stdin, replies)
    rospy.signal_shutdown("test finished")


if __name__ == "__main__":
    main()
