"""The per-user cache of what the message classes are made of (uh_runtime.message_cache).

What a process takes from the cache must equal what it would compute without it: the type store's
definitions, every type hash, the CDR bytes and the XTypes type information Cyclone DDS announces.
A changed input (a ``.msg`` file, the installed rosbags or cyclonedds, the code that builds the
classes) must never be served from an older file, and a cache that cannot be read or written
changes nothing but the time a start takes. Each test has its own empty cache directory.
"""
import json
import os

import pytest
from cyclonedds.idl._main import IDL
from cyclonedds.idl._support import Endianness
from cyclonedds.idl._xt_builder import XTBuilder

from uh_runtime import message_cache, messages
from uh_runtime.messages import KNOWN_TYPES, SERVICE_DEFINITIONS, dds_message, dds_service_message, typestore

#: Every message class a team's nodes make (their topics, rosout, parameter events and services).
NODE_TYPES = sorted({*KNOWN_TYPES.values(), 'rcl_interfaces/msg/ParameterEvent', 'rcl_interfaces/msg/Log',
                     'diagnostic_msgs/msg/DiagnosticArray', 'tf2_msgs/msg/TFMessage', 'nav_msgs/msg/Odometry'})
SERVICE_PARTS = [f'{service}_{part}' for service in SERVICE_DEFINITIONS for part in ('Request', 'Response')]


def _fresh_process_state(monkeypatch):
    """Forget the store and the classes, as a new process starts (restored after the test)."""
    monkeypatch.setattr(messages, '_store', None)
    monkeypatch.setattr(messages, '_store_digest', None)
    monkeypatch.setattr(messages, '_classes', {})


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """Give the test an empty cache directory (``UH_CACHE_DIR``) and the module state of a process's start."""
    monkeypatch.setenv('UH_CACHE_DIR', str(tmp_path / 'cache'))
    _fresh_process_state(monkeypatch)
    messages.uh_msg_texts.cache_clear()
    yield tmp_path / 'cache'
    messages.uh_msg_texts.cache_clear()


def _store_files(cache):
    return sorted(cache.glob('typestore-*.json'))


def test_the_store_from_the_cache_equals_the_store_built_without_it(cache, monkeypatch):
    built = typestore()
    hashes = {name: messages.type_hash(name) for name in NODE_TYPES}   # ROS's: char hashed as uint8
    assert len(_store_files(cache)) == 1
    _fresh_process_state(monkeypatch)
    cached = typestore()
    assert cached is not built and cached._types is None     # definitions only, so far
    assert cached.fielddefs == built.fielddefs
    for name in built.fielddefs:
        assert cached.hash_rihs01(name) == built.hash_rihs01(name), name
    assert {name: dds_message(name).__ros_typehash__ for name in NODE_TYPES} == hashes
    # rosbags' own classes (the reference serialiser) are built at first use, and are the same types
    assert sorted(cached.types) == sorted(built.types)
    ref = built.types['uh_msgs/msg/ActuatorFault'](
        header=built.types['std_msgs/msg/Header'](stamp=built.types['builtin_interfaces/msg/Time'](sec=3, nanosec=4),
                                                   frame_id='uh2'),
        uh_id=2, channel=1, rho=0.5, bias_constant=0.01, bias_amplitude=0.0, bias_frequency=0.0, onset_time=30.0,
        stuck_in_place=False)
    assert bytes(cached.serialize_cdr(ref, 'uh_msgs/msg/ActuatorFault')) == \
        bytes(built.serialize_cdr(ref, 'uh_msgs/msg/ActuatorFault'))
    assert len(_store_files(cache)) == 1


def test_a_changed_msg_file_is_not_served_from_the_cache(cache, tmp_path, monkeypatch):
    msgs = tmp_path / 'msg'
    msgs.mkdir()
    for path in messages.msg_search_path()[-1].glob('*.msg'):
        (msgs / path.name).write_text(path.read_text())
    monkeypatch.setenv('UH_MSGS_DIR', str(msgs))
    messages.uh_msg_texts.cache_clear()
    before = typestore().fielddefs['uh_msgs/msg/ActuatorFault']
    hash_before = messages.type_hash('uh_msgs/msg/ActuatorFault')

    with (msgs / 'ActuatorFault.msg').open('a') as out:
        out.write('float64 extra_field\n')
    messages.uh_msg_texts.cache_clear()
    _fresh_process_state(monkeypatch)
    after = typestore().fielddefs['uh_msgs/msg/ActuatorFault']
    assert after[1][:-1] == before[1] and after[1][-1][0] == 'extra_field'
    assert messages.type_hash('uh_msgs/msg/ActuatorFault') != hash_before
    assert 'extra_field' in [f.name for f in __import__('dataclasses').fields(dds_message('uh_msgs/msg/ActuatorFault'))]
    assert len(_store_files(cache)) == 2     # one per set of definitions


def test_the_key_follows_the_installed_files(tmp_path):
    import hashlib
    (tmp_path / 'store.py').write_text('x = 1\n')

    def digest():
        d = hashlib.sha256()
        message_cache.files_digest(d, tmp_path)
        return d.hexdigest()
    first = digest()
    assert digest() == first
    stat = (tmp_path / 'store.py').stat()
    os.utime(tmp_path / 'store.py', ns=(stat.st_atime_ns, stat.st_mtime_ns + 1_000_000))   # reinstalled
    assert digest() != first


def test_an_unreadable_cache_file_is_built_again(cache, monkeypatch):
    name = f'typestore-{messages._store_key()}.json'
    cache.mkdir()
    (cache / name).write_text('{"uh_msgs/msg/UHState": [[], [["x", [9, 0]]]]}')   # no such node type
    store = typestore()
    assert store.fielddefs == messages._build_store().fielddefs
    assert json.loads((cache / name).read_text())['uh_msgs/msg/UHState']     # rewritten whole
    _fresh_process_state(monkeypatch)
    (cache / name).write_text('{"truncat')
    assert typestore().fielddefs == store.fielddefs


def test_without_a_writable_cache_everything_works(tmp_path, monkeypatch):
    blocker = tmp_path / 'not-a-directory'
    blocker.write_text('')
    monkeypatch.setenv('UH_CACHE_DIR', str(blocker / 'cache'))
    _fresh_process_state(monkeypatch)
    cls = dds_message('uh_msgs/msg/ActuatorFault')
    cls.__idl__.populate()
    cls.__idl__.fill_type_data()
    assert cls.__idl__._xt_bytedata == _fresh_type_data(cls)
    assert typestore().fielddefs == messages._build_store().fielddefs


def test_without_a_home_directory_there_is_no_cache(monkeypatch):
    for name in ('UH_CACHE_DIR', 'XDG_CACHE_HOME'):
        monkeypatch.delenv(name, raising=False)

    def no_home():
        raise RuntimeError('Could not determine home directory.')
    monkeypatch.setattr(message_cache.Path, 'home', staticmethod(no_home))
    _fresh_process_state(monkeypatch)
    assert message_cache.cache_dir() is None
    assert message_cache.read('typestore-x.json', json.loads) is None
    message_cache.write('typestore-x.json', {})
    assert typestore().fielddefs == messages._build_store().fielddefs


def _fresh_type_data(cls):
    """Return the serialised TypeInformation and TypeMapping as cyclonedds' own ``IDL.fill_type_data`` makes them."""
    info, mapping = XTBuilder.process_type(cls)
    return (info.serialize(endianness=Endianness.Little, use_version_2=True)[4:],
            mapping.serialize(endianness=Endianness.Little, use_version_2=True)[4:])


def _classes():
    return [dds_message(name) for name in NODE_TYPES] + [dds_service_message(name) for name in SERVICE_PARTS]


def test_cached_type_information_equals_what_cyclonedds_builds(cache, monkeypatch):
    first = _classes()
    for cls in first:
        cls.__idl__.populate()
        cls.__idl__.fill_type_data()          # built, and written to the cache
    files = sorted(p.name for p in cache.glob('xtypes-*/*.json'))
    assert len(files) == len(first)
    _fresh_process_state(monkeypatch)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(XTBuilder, 'process_type', None)     # a second process only reads the files
        second = _classes()
        for cls in second:
            cls.__idl__.populate()
            cls.__idl__.fill_type_data()
    for old, new in zip(first, second, strict=False):
        assert new is not old and new.__idl__._xt_data[0] is None      # from the file
        assert new.__idl__._xt_bytedata == old.__idl__._xt_bytedata == _fresh_type_data(new), new
        # the objects are built when asked for, equal to cyclonedds' own
        info, mapping = XTBuilder.process_type(new)
        assert new.__idl__.get_type_info() == info and new.__idl__.get_type_mapping() == mapping
        assert new.__idl__.get_type_id() == info.complete.typeid_with_size.type_id


def test_type_information_is_cached_per_definitions_and_cyclonedds(cache, monkeypatch):
    cls = dds_message('uh_msgs/msg/UHState')
    name = cls.__idl__.cache_name
    assert name.startswith('xtypes-') and name.endswith('/uh_msgs.msg.UHState.json')
    wrapped = dds_service_message('rcl_interfaces/srv/GetParameters_Request')
    assert wrapped.__idl__.cache_name.endswith('/wrapped.rcl_interfaces.srv.GetParameters_Request.json')
    other = type('Other', (), {'__idl_typename__': 'Other'})
    message_cache.cache_type_data(other, 'uh_msgs/msg/UHState', 'another store')
    assert other.__idl__.cache_name != name
    monkeypatch.setattr(message_cache, '_cyclonedds_digest', lambda: 'another cyclonedds')
    message_cache.cache_type_data(other, 'uh_msgs/msg/UHState', messages._store_digest)
    assert other.__idl__.cache_name != name
    # definitions of unknown origin: cyclonedds' own type support, no file
    bare = type('Bare', (), {'__idl__': 'untouched'})
    message_cache.cache_type_data(bare, 'uh_msgs/msg/UHState', None)
    assert bare.__idl__ == 'untouched'
    assert isinstance(cls.__idl__, IDL)
