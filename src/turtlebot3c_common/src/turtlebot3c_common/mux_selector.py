"""Select an input of the teleop mux (topic_tools mux) without making the caller wait: the rospy side.

The joystick app selects on its buttons, the key app after a roscore restart; both call
from where a slow or absent mux must not stall them (a Joy callback, the key loop).
"""
import queue
import threading

import rospy


class MuxSelector:
    """Calls the mux's select service from a thread of its own, one request after another."""

    def __init__(self, service, service_class, wait, on_failure=None):
        self.service = service
        self.service_class = service_class  # topic_tools/MuxSelect, passed in: this package needs no topic_tools
        self.wait = wait  # s to wait for the service to be there
        self.on_failure = on_failure  # called with the topic when a selection did not happen
        self.requests = queue.Queue()
        threading.Thread(target=self._serve, daemon=True).start()

    def select(self, topic):
        self.requests.put(topic)

    def _serve(self):
        while not rospy.is_shutdown():
            topic = self.requests.get()
            if not self._select(topic) and self.on_failure is not None:
                self.on_failure(topic)

    def _select(self, topic):
        try:
            rospy.wait_for_service(self.service, timeout=self.wait)
            previous = rospy.ServiceProxy(self.service, self.service_class)(topic).prev_topic
        except rospy.ROSException:
            rospy.logwarn("mux: cannot select %s: %s not available within %.0f s (is turtlebot3c.teleop running?)",
                          topic, self.service, self.wait)
            return False
        except rospy.ServiceException as error:
            rospy.logwarn("mux: %s refused %s (not one of its inputs?): %s", self.service, topic, error)
            return False
        rospy.loginfo("mux: selected %s (was %s)", topic, previous or "none")
        return True
