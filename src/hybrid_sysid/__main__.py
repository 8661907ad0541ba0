from hybrid_sysid.cli.train import main

main()
