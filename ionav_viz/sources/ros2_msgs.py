"""ROS 2 message definitions (``ros2msg`` text with dependencies) for the MCAP files we write.

They are the standard ``sensor_msgs``/``geometry_msgs``/``nav_msgs`` definitions, so the files open in
Foxglove and in ``ros2 bag``.
"""

_SEP = "=" * 80 + "\n"

_TIME = "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
_HEADER = "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
_VECTOR3 = "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n"
_QUATERNION = "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n"
_TWIST = "MSG: geometry_msgs/Twist\ngeometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular\n"
_NAVSATSTATUS = (
    "MSG: sensor_msgs/NavSatStatus\n"
    "int8 STATUS_NO_FIX=-1\nint8 STATUS_FIX=0\nint8 STATUS_SBAS_FIX=1\nint8 STATUS_GBAS_FIX=2\n"
    "int8 status\n"
    "uint16 SERVICE_GPS=1\nuint16 SERVICE_GLONASS=2\nuint16 SERVICE_COMPASS=4\nuint16 SERVICE_GALILEO=8\n"
    "uint16 service\n"
)


def _join(main: str, *deps: str) -> str:
    return main + "".join(_SEP + d for d in deps)


IMU = _join(
    "std_msgs/Header header\n"
    "geometry_msgs/Quaternion orientation\nfloat64[9] orientation_covariance\n"
    "geometry_msgs/Vector3 angular_velocity\nfloat64[9] angular_velocity_covariance\n"
    "geometry_msgs/Vector3 linear_acceleration\nfloat64[9] linear_acceleration_covariance\n",
    _HEADER, _TIME, _QUATERNION, _VECTOR3,
)

NAVSATFIX = _join(
    "std_msgs/Header header\nsensor_msgs/NavSatStatus status\n"
    "float64 latitude\nfloat64 longitude\nfloat64 altitude\nfloat64[9] position_covariance\n"
    "uint8 COVARIANCE_TYPE_UNKNOWN=0\nuint8 COVARIANCE_TYPE_APPROXIMATED=1\n"
    "uint8 COVARIANCE_TYPE_DIAGONAL_KNOWN=2\nuint8 COVARIANCE_TYPE_KNOWN=3\n"
    "uint8 position_covariance_type\n",
    _HEADER, _TIME, _NAVSATSTATUS,
)

TWIST_STAMPED = _join("std_msgs/Header header\ngeometry_msgs/Twist twist\n", _HEADER, _TIME, _TWIST, _VECTOR3)

_POINT = "MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n"
_POSE = "MSG: geometry_msgs/Pose\ngeometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n"
_POSE_COV = "MSG: geometry_msgs/PoseWithCovariance\ngeometry_msgs/Pose pose\nfloat64[36] covariance\n"
_TWIST_COV = "MSG: geometry_msgs/TwistWithCovariance\ngeometry_msgs/Twist twist\nfloat64[36] covariance\n"

ODOMETRY = _join(
    "std_msgs/Header header\nstring child_frame_id\n"
    "geometry_msgs/PoseWithCovariance pose\ngeometry_msgs/TwistWithCovariance twist\n",
    _HEADER, _TIME, _POSE_COV, _POSE, _POINT, _QUATERNION, _TWIST_COV, _TWIST, _VECTOR3,
)

DEFINITIONS = {
    "sensor_msgs/msg/Imu": IMU,
    "sensor_msgs/msg/NavSatFix": NAVSATFIX,
    "geometry_msgs/msg/TwistStamped": TWIST_STAMPED,
    "nav_msgs/msg/Odometry": ODOMETRY,
}
