"""texplorer gui: the operator's web application (docs/operator.md), served by ``texplorer serve``.

``gui.app.create_app(Settings(db=...))`` builds the Flask app: start a scan, the guided steps
(docs/operator.md#procedure) over ``scanner.acquisition.session.Session``, the operator form, the summary with the
prediction, and the database
browser with export. It holds no business logic; see ``docs/gui.md``.
"""
