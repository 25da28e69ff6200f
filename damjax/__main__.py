from damjax.cli import entry

entry()
