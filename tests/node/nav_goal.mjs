// roslibjs (npm roslib 2.x) sends one Nav2 NavigateToPose goal to a robot and reports, one JSON
// object per line on stdout, what its callbacks saw. Run by tests/sim/test_sim_ros2_clients.py:
//   node nav_goal.mjs URL X Y YAW [cancel]
// With "cancel" it cancels the goal at its first feedback (roslibjs then calls the failed
// callback with "Action was canceled: ..."). Exits 0 once the result or the failure came, 1
// when nothing came within 10 s or the connection failed.
import { Action, Ros } from "roslib";

const [url, x, y, yaw, mode] = process.argv.slice(2);
const say = (obj) => process.stdout.write(JSON.stringify(obj) + "\n");
const timer = setTimeout(() => {
  say({ event: "timeout" });
  process.exit(1);
}, 10000);

const ros = new Ros({ url });
ros.on("error", (err) => {
  say({ event: "error", error: String(err) });
  process.exit(1);
});
ros.on("connection", () => {
  const action = new Action({
    ros,
    name: "/navigate_to_pose",
    actionType: "nav2_msgs/action/NavigateToPose",
  });
  const half = Number(yaw) / 2;
  const goal = {
    pose: {
      header: { stamp: { sec: 0, nanosec: 0 }, frame_id: "map" },
      pose: {
        position: { x: Number(x), y: Number(y), z: 0 },
        orientation: { x: 0, y: 0, z: Math.sin(half), w: Math.cos(half) },
      },
    },
    behavior_tree: "",
  };
  let feedbacks = 0;
  const finish = (obj) => {
    clearTimeout(timer);
    say({ ...obj, feedbacks });
    ros.close();
    setTimeout(() => process.exit(0), 50);
  };
  const id = action.sendGoal(
    goal,
    (result) => finish({ event: "result", result }),
    (feedback) => {
      feedbacks += 1;
      if (feedbacks === 1) {
        say({ event: "feedback", feedback });
        if (mode === "cancel") action.cancelGoal(id);
      }
    },
    (error) => finish({ event: "failed", error: String(error) }),
  );
  say({ event: "sent", id });
});
