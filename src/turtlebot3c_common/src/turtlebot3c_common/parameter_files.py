"""A node's parameters from a YAML file named on a command line (remap_bag --config, localize_bag
--config), and the checks their values share, from a file or from the ROS parameter server. No rospy."""
import math

import yaml


def load_parameter_file(path, what):
    """The mapping of parameters in the YAML file at `path` (an empty file: none); ValueError with
    one line saying what is wrong with it otherwise. `what` names the parameters ("SLAM parameters")."""
    try:
        with open(path, encoding="utf-8") as stream:
            values = yaml.safe_load(stream)
    except OSError as error:
        raise ValueError(f"cannot read {what} from {path}: {error.strerror or error}") from None
    except UnicodeDecodeError:
        raise ValueError(f"{path} is not a text file of {what}") from None
    except yaml.MarkedYAMLError as error:
        where = f" at line {error.problem_mark.line + 1}" if error.problem_mark else ""
        raise ValueError(f"{path} is not valid YAML: {error.problem}{where}") from None
    except yaml.YAMLError as error:
        raise ValueError(f"{path} is not valid YAML: {str(error).splitlines()[0]}") from None
    if values is None:
        return {}
    if not isinstance(values, dict):
        raise ValueError(f"{path} is not a YAML mapping of {what}")
    return values


def is_finite_number(value):
    """Whether a value read from a file is a finite number: not a bool, a string, NaN or an
    infinity, nor an integer too large for a float (YAML reads 1 and 400 zeros as one)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:
        return False


def finite_number(value, what):
    """`value` as a float, or ValueError saying that `what` ("SLAM parameter range_max") must be a
    finite number."""
    if not is_finite_number(value):
        raise ValueError(f"{what} must be a finite number, got {value!r}")
    return float(value)


def like_default(value, default, what, positive=False):
    """`value` as the type of `default` (bool, int or float), and more than 0 if `positive`, or
    ValueError saying what `what` ("amcl parameter kld_z") must be. A string is no number here,
    and "false" no switch."""
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise ValueError(f"{what} must be true or false, got {value!r}")
        return value
    number = finite_number(value, what)
    if isinstance(default, int):
        if int(number) != number:
            raise ValueError(f"{what} must be a whole number, got {value!r}")
        number = int(number)
    if positive and number <= 0:
        raise ValueError(f"{what} must be more than 0, got {value!r}")
    return number


def private_parameter(get_param, name, default, positive=False):
    """A node's private parameter `name` through `get_param` (rospy.get_param), of the type of
    `default`, and more than 0 if `positive`; ValueError with one line naming it otherwise."""
    return like_default(get_param("~" + name, default), default, f"parameter ~{name}", positive)
