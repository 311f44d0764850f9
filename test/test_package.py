"""package.xml is a valid format-3 ament_python manifest declaring what the code uses."""
from catkin_pkg.package import parse_package

from conftest import ROOT

RUN_DEPS = {'rclpy', 'std_msgs', 'geometry_msgs', 'sensor_msgs', 'diagnostic_msgs',
            'visualization_msgs', 'std_srvs', 'python3-numpy', 'python3-scipy'}


def _pkg():
    return parse_package(str(ROOT / 'package.xml'))


def test_package_xml_parses_and_validates():
    """catkin_pkg parses package.xml and its validate() raises nothing."""
    pkg = _pkg()
    pkg.validate()
    assert pkg.name == 'inertia_ros'
    assert pkg.package_format == 3


def test_build_type_is_ament_python():
    """The export declares ament_python, so colcon treats the package as ros.ament_python."""
    assert _pkg().get_build_type() == 'ament_python'


def test_declares_runtime_and_test_dependencies():
    """Every ROS package and system library the code imports is declared."""
    pkg = _pkg()
    run = {d.name for d in pkg.exec_depends + pkg.build_export_depends + pkg.build_depends}
    assert RUN_DEPS <= run, f'missing exec_depend: {sorted(RUN_DEPS - run)}'
    assert 'python3-pytest' in {d.name for d in pkg.test_depends}


def test_setup_py_version_matches_package_xml():
    """setup.py and package.xml carry the same version."""
    import re
    text = (ROOT / 'setup.py').read_text()
    m = re.search(r"version='([^']+)'", text)
    assert m and m.group(1) == _pkg().version
