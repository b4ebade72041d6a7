"""The server of ``skinsynth view``'s page: a viser server (its web client ships built inside the
viser wheel, so the page loads nothing from the network) holding the page for a view record
(:data:`PAGES`), the port checked first, served until a signal stops it. viser is imported when a
server starts, never with this module."""

import socket
import time
import webbrowser
from contextlib import contextmanager

from ...errors import OptionError
from .puppet_page import PuppetPage
from .records import PuppetView, SequenceView, SkinView, SynthesisView
from .sequence_page import SequencePage
from .skin_page import SkinPage
from .synthesis_page import SynthesisPage

#: The page of each view record.
PAGES = {PuppetView: PuppetPage, SkinView: SkinPage, SynthesisView: SynthesisPage, SequenceView: SequencePage}


def serve(view, host, port, label, on_listening, *, check_stop, warn, open_browser=False):
    """Serve ``view`` at http://host:port until a signal stops it (Ctrl-C: the command's signal
    handler raises in the wait); ``check_stop()`` every 0.2 s raises for a signal whose exception
    was swallowed (the command's recorded signal, ``formats.atomic.stop_if_received``);
    ``on_listening(url, port)`` once the page can be opened; ``warn(message)`` as :func:`open_page`.
    OptionError when the port is taken or the host cannot be listened on."""
    with open_page(view, host, port, label, warn=warn) as (server, _):
        shown = "localhost" if host in ("0.0.0.0", "::") else (f"[{host}]" if ":" in host else host)
        url = f"http://{shown}:{server.get_port()}"
        on_listening(url, server.get_port())
        if open_browser:
            webbrowser.open(url)
        while True:
            time.sleep(0.2)  # a signal's handler raises here (formats.atomic.raise_interrupted)
            check_stop()


@contextmanager
def open_page(view, host="127.0.0.1", port=0, label="skinsynth view", *, warn):
    """A viser server at host:port (0: any free port) holding ``view``'s page: yields (server,
    page), both stopped on leaving; ``warn(message)`` says what goes wrong while the page stays up
    (a failed prediction, an unsaved session: the command's ``warning: …`` line on stderr). What
    :func:`serve` serves; the tests drive a page through it without a browser. OptionError when
    the port is taken or the host cannot be listened on."""
    check_port(host, port)
    server = _start_server(host, port, label)
    page = None
    try:
        if port and server.get_port() != port:
            raise OptionError(_in_use(host, port))
        server.gui.configure_theme(control_layout="floating", control_width="medium", show_logo=False,
                                   show_share_button=False)
        page = PAGES[type(view)](server, view, warn)
        yield server, page
    finally:
        if page is not None:
            page.close()
        server.stop()


def check_port(host, port):
    """OptionError (one line) unless ``host`` can listen on ``port`` (0: any free port)."""
    try:
        family, kind, _, _, address = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0]
    except socket.gaierror as error:
        raise OptionError(f"--host {host}: cannot listen there ({error.strerror})") from None
    with socket.socket(family, kind) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as the server itself binds
        try:
            probe.bind(address)
        except OSError as error:
            if error.errno in (98, 48, 10048):  # EADDRINUSE (Linux, macOS, Windows)
                raise OptionError(_in_use(host, port)) from None
            raise OptionError(f"--host {host} --port {port}: cannot listen there ({error.strerror})") from None


def _in_use(host, port):
    return f"port {port} on {host} is in use: give another with --port (--port 0 picks a free one)"


def _start_server(host, port, label):
    """A viser server whose own messages (a banner on stdout, "Server stopped") are silenced: the
    command's stdout is its report alone (--json)."""
    import rich
    import viser

    rich.reconfigure(quiet=True)
    return viser.ViserServer(host=host, port=port, label=label, verbose=False)
